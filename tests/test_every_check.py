"""Every check for every shape and kind: one test per check, parametrised over the shapes,
each fitted through the one entry (``calibrate(robot, data)`` or ``calibrate(Problem(...))``).

Shapes: a chain measured by an instrument, a tree (two tools), one chain touching (each contact
kind), several chains touching (TALOS's two arms), the robot measuring itself (the TIAGo's
head camera seeing its hand), a measured term among touches (TALOS's head camera seeing
its left hand, with both arms' table touches, in one fit) and a camera's pixels (a UR5 seen
from the cell: one pixel term). Checks: validation data that are
the data are refused; a gross outlier is set aside (named by its row, and said in the
report's warnings); swapped joint columns and degrees are diagnosed (a one-line DataError
naming the mistake); too few rows for the unknowns are refused before any fit; a fit worse
than the registration on held-out rows is refused and writes no URDF; data no calibration
explains (another log's postures, another camera's intrinsics) are refused with a DataError
(and, the chain's poses, orientations of another row). None is skipped. The
data are simulated with a known truth, and the mistakes made by the test on the data it reads
(columns swapped, radians turned into degrees).
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from calib import (
    CalibError,
    CalibrationRefusedError,
    DataError,
    Problem,
    Term,
    calibrate,
    load_chain,
    load_robot,
    simulate,
    simulate_contacts,
)
from calib.measurements.tree_campaign import simulate_tree

TALOS = "talos_full_v2.urdf"
CONTACT_KINDS = ("plane", "plane-point", "fixed-point", "fixed-pose")
LEFT = ("left_sole_link", "gripper_left_base_link")
RIGHT = ("right_sole_link", "gripper_right_base_link")


@dataclass(frozen=True)
class Shape:
    """A way of building a problem: its data and how to fit them (``run(data, validate)``)."""

    data: Any
    run: Any
    parts: Any  # data -> its parts (one per term), each with q
    rebuild: Any  # (data, new parts) -> data

    def fit(self, data, validate=None):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return self.run(data, validate)


def _one(data) -> list:
    return [data]


def _measured(robot, data, params: str = "offsets") -> Shape:
    return Shape(
        data,
        lambda d, v: calibrate(robot, d, validate=v, params=params),
        _one,
        lambda d, parts: parts[0],
    )


def _contact(kind: str) -> Shape:
    chain = load_robot(TALOS, *LEFT)
    data = simulate_contacts(chain, 40, kind, seed=3).data
    return Shape(
        data,
        lambda d, v: calibrate(chain, d, validate=v, params="offsets"),
        _one,
        lambda d, parts: parts[0],
    )


def _chains() -> Shape:
    chains = [load_robot(TALOS, *pair) for pair in (LEFT, RIGHT)]
    data = [simulate_contacts(c, 40, "plane", seed=4).data for c in chains]

    def run(d, v):  # the first term validated on v
        checks = [v, *[None] * (len(d) - 1)]
        terms = zip(chains, d, checks, strict=True)
        return calibrate(Problem(tuple(Term(*t) for t in terms), params="offsets"))

    return Shape(data, run, list, lambda d, parts: [parts[0], *d[1:]])


def _camera_and_arms() -> Shape:
    """TALOS's head camera measuring the left hand, first, with both arms' table touches."""
    camera = load_robot(TALOS, "rgbd_optical_frame", LEFT[1])
    chains = [camera, *(load_robot(TALOS, *pair) for pair in (LEFT, RIGHT))]
    seen = simulate(camera, 40, measure="position", noise_mm=0.05, seed=5).measurements
    data = [seen, *(simulate_contacts(c, 40, "plane", seed=6).data for c in chains[1:])]

    def run(d, v):  # the first term validated on v
        checks = [v, *[None] * (len(d) - 1)]
        terms = zip(chains, d, checks, strict=True)
        return calibrate(Problem(tuple(Term(*t) for t in terms), params="offsets"))

    return Shape(data, run, list, lambda d, parts: [parts[0], *d[1:]])


def _ur5_pixels(noise_px: float, postures: int, seed: int, **errors):
    """A camera in the cell sees a board on a UR5's tool0: the chain, the camera, the data
    (simulated on a true robot ``errors`` away from the nominal, :func:`calib.simulate`'s
    default errors unless given)."""
    from pixel_setups import INTRINSICS, grid, look_at

    from calib.calibration.pixel_chain import PixelCamera, PixelData
    from calib.measurements.pixel_simulation import simulate_pixels
    from calib.measurements.true_robot import true_robot

    chain = load_chain("ur5", base="world", tool="tool0")
    C, target = look_at(np.array([1.6, 0.3, 0.8]), [0, 0, 0.3]), grid(4, 3, 0.03)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "true.urdf"
        true_robot([chain], path, seed=seed, **errors)
        truth = load_chain(str(path), base="world", tool="tool0")
    q = chain.random_configurations(postures, seed)
    obs = simulate_pixels(truth, "cam", C, INTRINSICS, target, q, noise_px=noise_px, seed=seed)
    camera = PixelCamera("cam", "world", INTRINSICS, None)
    return chain, camera, target, PixelData(camera, target, obs)


def _pixels() -> Shape:
    """A camera's pixels: one pixel term (its rows: each point in an image)."""
    chain, _, _, data = _ur5_pixels(0.2, 40, 7)

    def run(d, v):  # validation: the same camera's rows
        v = v if v is None else dataclasses.replace(d, obs=v)
        return calibrate(Problem((Term(chain, d, v),), params="offsets"))

    return Shape(
        data, run, lambda d: [d.obs], lambda d, parts: dataclasses.replace(d, obs=parts[0])
    )


def _shapes() -> dict[str, Any]:
    ur5 = load_chain("ur5")
    tree = load_robot("talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"])
    head = load_chain("tiago", "xtion_optical_frame", "arm_tool_link")
    return {
        "chain": lambda: _measured(
            ur5, simulate(ur5, 40, noise_mm=0.05, seed=1, measure="pose").measurements
        ),
        "tree": lambda: _measured(
            tree, simulate_tree(tree, 40, noise_mm=0.05, seed=2).measurements, "complete"
        ),
        "on-robot": lambda: _measured(
            head, simulate(head, 40, measure="position", noise_mm=0.05, seed=3).measurements
        ),
        **{f"contacts-{k}": (lambda k=k: _contact(k)) for k in CONTACT_KINDS},
        "chains": _chains,
        "measured-and-touches": _camera_and_arms,
        "pixels": _pixels,
    }


SHAPES = _shapes()
"""Every shape and kind, built when a test asks for it."""


def _with_q(shape: Shape, q: np.ndarray):
    """The data with the first term's joint columns replaced."""
    first = shape.parts(shape.data)[0]
    return shape.rebuild(shape.data, [dataclasses.replace(first, q=q)])


def _rows(shape: Shape, keep: np.ndarray):
    """The data with the first term's rows ``keep`` only (a boolean mask)."""
    first = shape.parts(shape.data)[0]
    fields = {"q": first.q[keep]}
    for name in ("position", "quaternion", "ids", "tool", "rows", "camera", "point", "pixels"):
        value = getattr(first, name, None)
        if value is not None:
            fields[name] = (
                value[keep] if isinstance(value, np.ndarray) else tuple(np.array(value)[keep])
            )
    return shape.rebuild(shape.data, [dataclasses.replace(first, **fields)])


@pytest.fixture(params=sorted(SHAPES))
def shape(request) -> Shape:
    return SHAPES[request.param]()


def test_validation_that_is_the_data_is_refused(shape):
    first = shape.parts(shape.data)[0]
    with pytest.raises(DataError, match="held out must mean held out"):
        shape.fit(shape.data, first)


def test_a_gross_outlier_is_set_aside(shape):
    """One configuration's joint 2 off by 0.3 rad: set aside, named by its row; the others
    kept. The result's report lists it (format 3 ``outliers``). The reading moves toward the
    middle of the joint's readings: one far past a joint limit is refused, not set aside."""
    first = shape.parts(shape.data)[0]
    q = first.q.copy()
    q[11, 1] += 0.3 if q[11, 1] < np.median(q[:, 1]) else -0.3
    bad = _with_q(shape, q)
    result = shape.fit(bad)
    report = result.to_dict()
    # a tree's report has a term per tool, each of the problem's one term: its rows by row number
    first_terms = range(len(report["terms"])) if report["shape"] == "tree" else (0,)
    rows = [o["row"] for o in report["outliers"] if o["term"] in first_terms]
    assert rows == [12], report["outliers"]  # row 12 of the data (11 + 1: no file)
    assert any("set aside" in w for w in report["warnings"]), report["warnings"]


def test_swapped_joint_columns_are_diagnosed(shape):
    first = shape.parts(shape.data)[0]
    q = first.q.copy()
    q[:, [1, 2]] = q[:, [2, 1]]
    with pytest.raises(DataError, match=r"swapped|a wrong column"):
        shape.fit(_with_q(shape, q))


def test_degrees_are_diagnosed(shape):
    first = shape.parts(shape.data)[0]
    with pytest.raises(DataError, match="degrees"):
        shape.fit(_with_q(shape, np.degrees(first.q)))


def test_too_few_rows_are_refused_before_any_fit(shape):
    keep = np.zeros(shape.parts(shape.data)[0].q.shape[0], dtype=bool)
    keep[:2] = True
    with pytest.raises(CalibError, match=r"needs at least|at least \d+ are needed"):
        shape.fit(_rows(shape, keep))


NOISE_ONLY = {"error_mm": 0.0, "error_mrad": 0.0}
"""A campaign on the nominal robot itself: what a fit can learn from it is the noise only."""


def _overfit(name: str):
    """Few noisy rows of the nominal robot, half held out: the fit of every offset (the tree:
    every parameter) learns the noise, so it is worse than the registration (the truth) on the
    held-out rows. The problem of ``name``'s shape, fitted."""
    talos = [load_robot(TALOS, *pair) for pair in (LEFT, RIGHT)]
    opts = {"params": "offsets", "holdout": 0.5, "seed": 0}
    if name in ("chain", "on-robot"):
        chain = (
            load_chain("ur5")
            if name == "chain"
            else load_chain("tiago", "xtion_optical_frame", "arm_tool_link")
        )
        kind = "pose" if name == "chain" else "position"
        data = simulate(chain, 24, kind, noise_mm=1.0, seed=1, **NOISE_ONLY).measurements
        return calibrate(chain, data, **opts)
    if name == "tree":
        tree = load_robot(
            "talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
        )
        data = simulate_tree(tree, 24, noise_mm=1.0, seed=2, **NOISE_ONLY).measurements
        return calibrate(tree, data, **{**opts, "params": "complete"})
    if name.startswith("contacts-"):
        kind = name.removeprefix("contacts-")
        touches = 40 if kind == "plane-point" else 24  # one equation a touch: more touches
        data = simulate_contacts(talos[0], touches, kind, seed=3, noise_mrad=3.0, **NOISE_ONLY)
        return calibrate(talos[0], data.data, **opts)
    terms = [
        Term(c, simulate_contacts(c, 24, "plane", seed=4, noise_mrad=3.0, **NOISE_ONLY).data)
        for c in talos
    ]
    if name == "pixels":  # few postures, 3 px of noise: the offsets learn the noise
        chain, _, _, data = _ur5_pixels(3.0, 8, 1, **NOISE_ONLY)
        return calibrate(Problem((Term(chain, data),), **opts))
    if name == "measured-and-touches":
        camera = load_robot(TALOS, "rgbd_optical_frame", LEFT[1])
        seen = simulate(camera, 24, "position", noise_mm=1.0, seed=5, **NOISE_ONLY)
        terms.insert(0, Term(camera, seen.measurements))
    return calibrate(Problem(tuple(terms), **opts))


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_a_fit_worse_than_the_registration_is_refused(name, tmp_path):
    """The registration of the nominal robot is the truth here: the fitted model, worse on the
    held-out rows, is refused: no URDF is written, only the report, which says so."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = _overfit(name)
    assert not result.accepted
    assert "worse than the registration" in result.refusal
    with pytest.raises(CalibrationRefusedError):
        result.write(tmp_path / "cal.urdf", report=tmp_path / "r.json")
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]
    report = json.loads((tmp_path / "r.json").read_text())
    assert "worse than the registration" in report["refusal"]


def _unexplained(shape: Shape):
    """The first term's data no calibration explains: each joint column shuffled across the
    rows (another log's postures); a camera's pixels read with another camera's intrinsics
    (focal lengths half the true ones: its postures shuffled would put the target behind it,
    refused before any fit)."""
    first = shape.parts(shape.data)[0]
    if hasattr(first, "pixels"):
        intrinsics = shape.data.camera.intrinsics
        lens = intrinsics.camera
        other = dataclasses.replace(lens, fx=lens.fx / 2, fy=lens.fy / 2)
        camera = dataclasses.replace(
            shape.data.camera, intrinsics=dataclasses.replace(intrinsics, camera=other)
        )
        return dataclasses.replace(shape.data, camera=camera)
    rng = np.random.default_rng(11)
    return _with_q(shape, np.column_stack([rng.permutation(c) for c in first.q.T]))


def test_data_no_calibration_explains_are_refused(shape):
    """Registered and calibrated, they stay far above any geometric error (pixels: and over
    ``REFUSED_PX``): one DataError names the data and the way out, and no result (no URDF)
    is made. A stalled fit on them is refused so too, not sent to a larger iteration cap."""
    with pytest.raises(DataError, match=r"do not match .*(another robot's|another camera's)"):
        shape.fit(_unexplained(shape))


def test_orientations_no_calibration_explains_are_refused():
    """The chain's poses with every row's orientation another row's (another frame's
    orientations): the positions fit, the orientations are refused, the positions alone
    named as the way out. Only the chain measures orientations among the shapes."""
    shape = SHAPES["chain"]()
    data = shape.data
    turned = data.quaternion[np.random.default_rng(11).permutation(data.m)]
    with pytest.raises(DataError, match=r"orientations do not match .*positions alone"):
        shape.fit(dataclasses.replace(data, quaternion=turned))
    assert shape.fit(data.position_only()).accepted  # the way out
