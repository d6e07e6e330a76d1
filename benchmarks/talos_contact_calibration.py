"""TALOS flush contacts: 5-fold cross-validated held-out gaps of one chain touching a table.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/talos_contact_calibration.py``

For each side (left, right) and each parameter level, the touches are split into 5 folds
(seeded, within the plane); each fold is held out in turn, the calibration runs on the
other four (``validate=`` the held fold), and the held fold's gaps are pooled: RMS height [mm],
roll and pitch [deg] of the calibrated model (``fit``), of what calib delivers (the
registration when the model is refused, ``delivered``) and of the registration alone (the
nominal robot with its own plane and contact, ``baseline``). Then the median time of the
default calibration on all touches (target < 1 s).

``elastic`` rows add the joint compliances (``elastic=True``: gravity torques of the robot
standing on the chain's sole, :mod:`calib.kinematics.standing`), under three assumptions on
the load split with the other foot: ``single`` (the standing foot carries the whole robot,
the default), ``own-leg`` (the other foot carries its own leg) and ``half`` (the other foot
pushes up with half the robot's weight at its sole). Their ``urdf`` column scores the
calibrated URDF alone (compliance left out) on the same held-out touches.

The rigid rows go through :func:`calib.calibrate` and the elastic rows through
``calibrate_contacts`` (which takes the load split with another foot, ``support``): both the
joint engine's fit of one contact term.
"""

from __future__ import annotations

import statistics
import time
import warnings
from pathlib import Path

import numpy as np

from calib import calibrate, load_robot
from calib.calibration.entry import calibrate_contacts
from calib.kinematics.standing import Support
from calib.measurements.contact_campaign import ContactData, read_contacts

DATA = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
URDF = "talos_full_v2.urdf"
CONTACT = (0.0, 0.0, -0.12)
FOLDS = 5
SEED = 0


def _pooled(parts: list[tuple[int, float, float, float]]) -> tuple[float, float, float]:
    m = sum(p[0] for p in parts)
    return tuple(  # type: ignore[return-value]
        float(np.sqrt(sum(p[0] * p[k] ** 2 for p in parts) / m)) for k in (1, 2, 3)
    )


def _row(s) -> tuple[int, float, float, float]:
    return (s.m, s.height_rms_mm, s.roll_rms_deg, s.pitch_rms_deg)


def cross_validate(chain, data: ContactData, params: str | None, **elastic):
    """Pooled held-out (fit, delivered, baseline, URDF alone) RMS and the refused folds."""
    folds = np.array_split(np.random.default_rng(SEED).permutation(data.m), FOLDS)
    fit, delivered, base, alone, refused = [], [], [], [], 0
    for f in range(FOLDS):
        train = np.setdiff1d(np.arange(data.m), folds[f])
        r, stats = _fit(chain, data.subset(train), data.subset(folds[f]), params, elastic)
        h, b = stats["held_out"], stats["held_out_registration"]
        row, brow = _row(h), _row(b)
        fit.append(row)
        base.append(brow)
        alone.append(_row(stats.get("held_out_urdf", h)))
        delivered.append(row if r.accepted else brow)
        refused += not r.accepted
    return _pooled(fit), _pooled(delivered), _pooled(base), _pooled(alone), refused


def _fit(chain, train: ContactData, held: ContactData, params, elastic: dict):
    """One fold's calibration and its gap statistics (``train``, ``held_out``, ...)."""
    if not elastic:
        r = calibrate(chain, train, marker=CONTACT, params=params, validate=held, seed=SEED)
        return r, r.chains[0].stats
    r = calibrate_contacts(
        chain, train, contact=CONTACT, params=params, validate=held, seed=SEED, **elastic
    )
    return r, r.stats


def _variants(side: str) -> dict[str, dict]:
    """The ``calibrate_contacts`` arguments of each row: rigid, then elastic load splits."""
    other = f"{'right' if side == 'left' else 'left'}_sole_link"
    return {
        "": {},
        " elastic single": {"elastic": True},
        " elastic own-leg": {"elastic": True, "support": Support(other)},
        " elastic half": {"elastic": True, "support": Support(other, 0.5)},
    }


def main() -> None:
    warnings.simplefilter("ignore")
    for side in ("left", "right"):
        chain = load_robot(URDF, f"{side}_sole_link", f"gripper_{side}_base_link")
        data = read_contacts(DATA / f"{side}_train.csv", chain, "plane")
        for params in (None, "offsets", "frames"):
            for label, elastic in _variants(side).items():
                if params == "frames" and elastic:
                    continue
                fit, dlv, base, alone, refused = cross_validate(chain, data, params, **elastic)
                name = (params or "auto") + label
                print(
                    f"{side:5s} {name:24s} fit {fit[0]:6.2f} mm {fit[1]:.2f} {fit[2]:.2f} deg"
                    f" | delivered {dlv[0]:6.2f} {dlv[1]:.2f} {dlv[2]:.2f}"
                    f" | urdf {alone[0]:6.2f} {alone[1]:.2f} {alone[2]:.2f}"
                    f" | baseline {base[0]:6.2f} {base[1]:.2f} {base[2]:.2f} | refused {refused}/5",
                    flush=True,
                )
        for elastic in (False, True):
            times = []
            for _ in range(5):
                t = time.perf_counter()
                if elastic:
                    calibrate_contacts(chain, data, contact=CONTACT, elastic=True)
                else:
                    calibrate(chain, data, marker=CONTACT)
                times.append(time.perf_counter() - t)
            print(
                f"{side:5s} {'elastic' if elastic else 'default'} calibration on {data.m} "
                f"touches: median {1e3 * statistics.median(times):.0f} ms"
            )


if __name__ == "__main__":
    main()
