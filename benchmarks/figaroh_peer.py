"""FIGAROH's structural step, timed in FIGAROH's own environment (not calib's).

Run by ``bench_identifiability.py`` with the Python of a venv holding ``figaroh==1.0.2``:

    python figaroh_peer.py NAME URDF TOOL [NAME URDF TOOL ...]

For each chain (base: the URDF root), ``calculate_base_kinematics_regressor`` draws 100
random configurations itself, builds the kinematic regressor of the tool position, removes
the columns without effect and selects the base parameters by QR: the same step calib
times. The peer stays up so that the benchmark can alternate calib's and FIGAROH's batches:
it first prints one JSON line, name -> number of base parameters, then reads lines
``NAME REPEATS`` on stdin, runs the step ``REPEATS`` times (after one warm-up call) and
answers each with one JSON line: the list of wall times [ms]. End of input ends it.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import time

import pinocchio as pin
from figaroh.calibration.calibration_tools import calculate_base_kinematics_regressor


def structural_step(urdf: str, tool: str):
    """A function running FIGAROH's step on a chain, position of the tool, m = 100."""
    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    tool_id = model.getFrameId(tool)
    joints = list(model.supports[model.frames[tool_id].parentJoint])[1:]
    config = {
        "NbSample": 100,
        "q0": pin.neutral(model),
        "config_idx": [model.joints[j].idx_q for j in joints],
        "start_frame": "universe",
        "end_frame": tool,
        "IDX_TOOL": tool_id,
        "measurability": [True, True, True, False, False, False],
        "calibration_index": 3,
        "calib_model": "full_params",
        "free_flyer": False,
        "NbMarkers": 1,
        "random_seed": 0,
    }

    def run():
        with contextlib.redirect_stdout(io.StringIO()):  # it prints the regressor shapes
            return calculate_base_kinematics_regressor([], model, data, dict(config, param_name=[]))

    return run


def main() -> None:
    args = sys.argv[1:]
    steps = {
        name: structural_step(urdf, tool)
        for name, urdf, tool in zip(args[::3], args[1::3], args[2::3], strict=True)
    }
    print(json.dumps({name: len(run()[3]) for name, run in steps.items()}), flush=True)
    for line in sys.stdin:
        name, repeats = line.split()
        run = steps[name]
        run()
        times = []
        for _ in range(int(repeats)):
            t0 = time.perf_counter()
            run()
            times.append(1e3 * (time.perf_counter() - t0))
        print(json.dumps(times), flush=True)


if __name__ == "__main__":
    main()
