"""An independent fit for the tests: Pinocchio poses, scipy's least squares, no calib.

A chain measured by an instrument (one marker's position per row) is fitted at one of
calib's parameter levels, spelled here with redundant parameters (scipy's trust region copes
with the rank deficit): the predictions of a level are those of its identifiable parameters,
so the held-out errors are the ones a correct calib fit of that level must give.

- ``frames``: the base frame's pose in the instrument's (6) and the marker in the tool (3);
- ``offsets``: and every chain joint's offset;
- ``complete``: and a 6-DOF error on every chain joint's placement (any geometry).
"""

from __future__ import annotations

import csv

import numpy as np
import pinocchio as pin
from pinref import pin_config, pin_frame
from scipy.optimize import least_squares


def csv_rows(path, joint_names, point: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """A measurement file's joint positions and one point, read by the csv module alone."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    q = np.array([[float(r[name]) for name in joint_names] for r in rows])
    return q, np.array([[float(r[f"{c}{point}"]) for c in "xyz"] for r in rows])


class PinChainFit:
    """The chain between two frames of a URDF file, posed once per row by Pinocchio."""

    def __init__(self, urdf, base: str, tool: str) -> None:
        model = pin.buildModelFromUrdf(str(urdf))
        data = model.createData()
        b, t = pin_frame(model, base), pin_frame(model, tool)
        self.model, self.data = model, data
        support = list(model.supports[model.frames[t].parentJoint])
        self.joints = support[support.index(model.frames[b].parentJoint) + 1 :]
        self.names = [model.names[j] for j in self.joints]
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        first = self.joints[0]
        self.prefix = (data.oMf[b].inverse() * data.oMi[model.parents[first]]).homogeneous
        self.tail = (data.oMi[self.joints[-1]].inverse() * data.oMf[t]).homogeneous
        self.placements = [model.jointPlacements[j].homogeneous for j in self.joints]
        self.axes = [np.ravel(data.joints[j].S).copy() for j in self.joints]

    def motions(self, q: np.ndarray) -> np.ndarray:
        """Each joint's own motion ``(m, n, 4, 4)``: its placement's inverse times liMi."""
        out = np.empty((len(q), len(self.joints), 4, 4))
        for i, qi in enumerate(q):
            pin.forwardKinematics(self.model, self.data, pin_config(self.model, self.joints, qi))
            for k, j in enumerate(self.joints):
                placement = self.model.jointPlacements[j]
                out[i, k] = (placement.inverse() * self.data.liMi[j]).homogeneous
        return out

    def points(self, x: np.ndarray, level: str, motions: np.ndarray) -> np.ndarray:
        """The marker in the instrument's frame ``(m, 3)`` for parameters x of a level."""
        n = len(self.joints)
        H = np.broadcast_to(pin.exp6(x[:6]).homogeneous @ self.prefix, (len(motions), 4, 4))
        for k in range(n):
            placed = self.placements[k]
            if level == "offsets":
                placed = placed @ pin.exp6(self.axes[k] * x[9 + k]).homogeneous
            elif level == "complete":
                placed = placed @ pin.exp6(x[9 + 6 * k : 15 + 6 * k]).homogeneous
            H = H @ placed @ motions[:, k]
        marker = self.tail @ np.append(x[6:9], 1.0)
        return (H @ marker)[:, :3]

    def held_out_mm(self, level: str, train, test) -> tuple[float, float]:
        """RMS and max [mm] on ``test`` of the fit of ``train`` (each a pair q, points)."""
        size = 9 + {"frames": 0, "offsets": 1, "complete": 6}[level] * len(self.joints)
        seen = self.motions(train[0])
        fit = least_squares(
            lambda x: (self.points(x, level, seen) - train[1]).ravel(),
            np.zeros(size),
            xtol=1e-14,
            ftol=1e-14,
            gtol=1e-14,
        )
        predicted = self.points(fit.x, level, self.motions(test[0]))
        errors = 1e3 * np.linalg.norm(predicted - test[1], axis=1)
        return float(np.sqrt(np.mean(errors**2))), float(errors.max())
