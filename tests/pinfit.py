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
import itertools

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


def _line_twist(point: np.ndarray, direction: np.ndarray, turn: bool) -> np.ndarray:
    """The unit twist (linear, angular) of a turn about, or a slide along, a line."""
    if not turn:
        return np.concatenate([direction, np.zeros(3)])
    return np.concatenate([np.cross(point, direction), direction])


def _foot(a: np.ndarray, point: np.ndarray, u: np.ndarray, p: np.ndarray, entry: np.ndarray):
    """Foot on the line (point, a) of the common normal to the line (p, u), and its direction.
    Parallel lines: the foot is ``entry`` projected on the first line (Khalil's convention
    takes the previous frame's origin), the normal toward the second line."""
    n = np.cross(a, u)
    if np.linalg.norm(n) > 1e-9:
        s, _ = np.linalg.lstsq(np.column_stack([a, -u]), p - point, rcond=None)[0]
        return point + s * a, n / np.linalg.norm(n)
    foot = point + a * (a @ (entry - point))
    n = (p - foot) - a * (a @ (p - foot))
    if np.linalg.norm(n) < 1e-9:  # the same line: any normal
        n = np.cross(a, np.eye(3)[np.argmin(np.abs(a))])
    return foot, n / np.linalg.norm(n)


class PinMdhFit(PinChainFit):
    """The chain's base frame and marker, and named modified-DH parameters.

    Each parameter is a unit twist: a turn about, or a slide along, its line (Khalil's
    ``Rot(y, beta) Rot(x, alpha) Trans(x, d)`` on the common normal x from the previous
    joint's axis to the joint's, y = z x x; ``Rot(z, theta) Trans(z, r)`` on the joint's
    axis z; before the first joint, the base frame's z). The lines are those of the neutral
    posture. The named parameters of a joint make one error ``E = [exp(w) | v]`` after its
    placement, ``(v, w)`` their twists (in the joint's frame) times their values: the
    placement errors of docs/developers/engine.md#placements, which calib fits. To first
    order this is the MDH row's change; beyond, E is the model (it is not MDH's)."""

    def _lines(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """The base frame's z line, then each joint's axis line (point, direction) in the base
        frame, with the common normals' feet (Khalil's frame origins) ``[(point, dir, foot)]``."""
        model, data = self.model, self.data
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        base = pin.SE3(self.prefix) * data.oMi[model.parents[self.joints[0]]].inverse()
        lines = [(np.zeros(3), np.array([0.0, 0.0, 1.0]))]
        for j, S in zip(self.joints, self.axes, strict=True):
            M = base * data.oMi[j]
            axis = S[3:] if np.linalg.norm(S[3:]) > 0 else S[:3]
            lines.append((M.translation, M.rotation @ axis))
        feet, normals = [np.zeros(3)], []
        for (point, a), (p, u) in itertools.pairwise(lines):
            foot, n = _foot(a, point, u, p, feet[-1])
            feet.append(foot)
            normals.append(n)
        return [
            (*line, foot, n) for line, foot, n in zip(lines[1:], feet[1:], normals, strict=True)
        ]

    def twists(self, names) -> list[tuple[int, np.ndarray]]:
        """Each name's joint index and unit twist ``(v, w)`` in the joint's frame."""
        model, data = self.model, self.data
        lines = self._lines()
        base = pin.SE3(self.prefix) * data.oMi[model.parents[self.joints[0]]].inverse()
        out = []
        for name in names:
            joint, kind = name.split(":")
            k, kind = self.names.index(joint), kind.rstrip("0123456789")
            point, u, foot, n = lines[k]
            previous = lines[k - 1][1] if k > 0 else np.array([0.0, 0.0, 1.0])
            if kind in ("theta", "r"):
                twist = _line_twist(point, u, kind == "theta")
            else:
                direction = np.cross(previous, n) if kind in ("beta", "y") else n
                twist = _line_twist(foot, direction, kind in ("alpha", "beta"))
            M = base * data.oMi[self.joints[k]]
            out.append((k, M.actInv(pin.Motion(twist)).vector))  # in the joint's frame
        return out

    def mdh_points(self, x: np.ndarray, twists, motions: np.ndarray) -> np.ndarray:
        """The marker ``(m, 3)`` for the frames' 9 parameters and the named ones' values."""
        H = np.broadcast_to(pin.exp6(x[:6]).homogeneous @ self.prefix, (len(motions), 4, 4))
        for k in range(len(self.joints)):
            error = np.zeros(6)
            for value, (j, twist) in zip(x[9:], twists, strict=True):
                if j == k:
                    error += value * twist
            E = np.eye(4)
            E[:3, :3], E[:3, 3] = pin.exp3(error[3:]), error[:3]
            H = H @ self.placements[k] @ E @ motions[:, k]
        return (H @ (self.tail @ np.append(x[6:9], 1.0)))[:, :3]

    def held_out_named_mm(self, names, train, test, strength=0.0) -> tuple[float, float]:
        """RMS and max [mm] on ``test`` of a fit of the frames and ``names`` on ``train``.

        ``strength``: a prior pulling each named parameter to its nominal value, with weight
        ``sqrt(strength) * |column|`` (its residuals' derivative at the registration).
        """
        twists, seen = self.twists(names), self.motions(train[0])

        def residuals(x):
            return (self.mdh_points(x, twists, seen) - train[1]).ravel()

        x0 = np.zeros(9 + len(twists))
        x0[:9] = self._fit(residuals, x0, np.zeros(0))[:9]
        h, columns = 1e-7, []
        for k in range(9, len(x0)):
            step = np.zeros(len(x0))
            step[k] = h
            columns.append((residuals(x0 + step) - residuals(x0 - step)) / (2 * h))
        weights = np.sqrt(strength) * np.linalg.norm(columns, axis=1)
        x = self._fit(residuals, x0, weights)
        predicted = self.mdh_points(x, twists, self.motions(test[0]))
        errors = 1e3 * np.linalg.norm(predicted - test[1], axis=1)
        return float(np.sqrt(np.mean(errors**2))), float(errors.max())

    @staticmethod
    def _fit(residuals, x0, weights) -> np.ndarray:
        """The least squares of ``residuals`` and the prior rows ``weights * x[9:]`` from x0
        (no weights: the frames alone, the named parameters held at 0)."""
        frames = len(weights) == 0
        fit = least_squares(
            lambda y: np.concatenate(
                [residuals(np.r_[y, x0[9:]]) if frames else residuals(y), weights * y[9:]]
            ),
            x0[:9] if frames else x0,
            xtol=1e-14,
            ftol=1e-14,
            gtol=1e-14,
        )
        return np.r_[fit.x, x0[9:]] if frames else fit.x
