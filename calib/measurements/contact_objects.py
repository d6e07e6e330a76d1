"""Objects given to a contact campaign: a known floor, table, point or pose, by name.

A simulation can touch given objects (:func:`~.contact_campaign.simulate_contacts`'s
``objects``) and a contact fit can hold a known plane (``known_planes`` of
:class:`~calib.calibration.problem.Problem`). Each object is a frame ``(4, 4)`` in the chain's
base frame [m]: a plane's z axis is its normal (its origin a point of it), a point is its
origin, a pose the whole frame. A plane may also be given as a point and a normal,
``(x, y, z, nx, ny, nz)``, and a point as ``(x, y, z)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..exceptions import InvalidArgumentError
from ..identification.contacts import Contact, PlaneContact, PlanePointContact

__all__ = [
    "MAX_OBJECT_DISTANCE",
    "given_objects",
    "object_frame",
    "plane_rotation",
    "plane_through",
    "term_planes",
]

_PLANES = (PlaneContact, PlanePointContact)

MAX_OBJECT_DISTANCE = 100.0
"""Farthest an object may be given from the base frame [m] (further: millimetres?)."""


def plane_rotation(n: np.ndarray) -> np.ndarray:
    """The rotation ``(3, 3)`` of a plane whose unit normal is ``n``.

    Its z is ``n``, its x the base x made perpendicular to it (the base y when the normal is
    near x).
    """
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    ex = helper - (helper @ n) * n
    ex /= np.linalg.norm(ex)
    return np.column_stack([ex, np.cross(n, ex), n])


def plane_through(point, normal) -> np.ndarray:
    """The plane ``(4, 4)`` through ``point`` [m], z along ``normal`` (:func:`plane_rotation`)."""
    n = np.asarray(normal, dtype=float)
    T = np.eye(4)
    T[:3, :3] = plane_rotation(n / np.linalg.norm(n))
    T[:3, 3] = np.asarray(point, dtype=float)
    return T


def object_frame(value, kind: Contact, name: str) -> np.ndarray:
    """One given object as a frame ``(4, 4)`` in the base frame, checked.

    Raises:
        InvalidArgumentError: Not a rigid frame, a plane's point and normal or a point's
            coordinates; a NaN, a zero normal, or an object further than
            :data:`MAX_OBJECT_DISTANCE`.
    """
    plane = kind.object_name == "plane"
    forms = "a frame (4, 4)" + (
        ", or a point and a normal (x, y, z, nx, ny, nz)"
        if plane
        else ", or its position (x, y, z)"
        if kind.object_name == "point"
        else ""
    )
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"{kind.object_name} '{name}': give {forms} [m]") from None
    if not np.all(np.isfinite(v)):
        raise InvalidArgumentError(f"{kind.object_name} '{name}': its numbers must be finite")
    if v.shape == (4, 4):
        rigid = np.allclose(v[:3, :3] @ v[:3, :3].T, np.eye(3), atol=1e-9)
        if not rigid or np.linalg.det(v[:3, :3]) < 0 or not np.allclose(v[3], [0, 0, 0, 1]):
            raise InvalidArgumentError(f"{kind.object_name} '{name}': not a rigid frame (4, 4)")
        T = v.copy()
    elif plane and v.shape == (6,):
        if np.linalg.norm(v[3:]) < 1e-9:
            raise InvalidArgumentError(f"plane '{name}': its normal is zero")
        T = plane_through(v[:3], v[3:])
    elif kind.object_name == "point" and v.shape == (3,):
        T = np.eye(4)
        T[:3, 3] = v
    else:
        raise InvalidArgumentError(f"{kind.object_name} '{name}': give {forms} [m]")
    far = float(np.linalg.norm(T[:3, 3]))
    if far > MAX_OBJECT_DISTANCE:
        raise InvalidArgumentError(
            f"{kind.object_name} '{name}' is {far:g} m from the base frame, more than "
            f"{MAX_OBJECT_DISTANCE:g} m: its coordinates are metres (millimetres?)"
        )
    return T


def given_objects(objects: Mapping, kind: Contact) -> dict[str, np.ndarray]:
    """Objects by name ``{name: frame or numbers}`` as frames ``(4, 4)``, checked.

    Raises:
        InvalidArgumentError: Not a non-empty mapping of names, or an object
            :func:`object_frame` refuses.
    """
    if not isinstance(objects, Mapping) or not objects:
        raise InvalidArgumentError(
            f"give the {kind.object_name}s by name, e.g. {{'floor': (0, 0, 0, 0, 0, 1)}}"
        )
    bad = [k for k in objects if not isinstance(k, str) or not k.strip() or "," in k]
    if bad:
        raise InvalidArgumentError(
            f"a {kind.object_name}'s name is a non-empty text without a comma, got {bad[0]!r:.40}"
        )
    return {name.strip(): object_frame(v, kind, name) for name, v in objects.items()}


def term_planes(chains: Sequence, data: Sequence, given: Mapping | None) -> list[dict | None]:
    """Each term's planes given (``{id: frame}``, every plane it touches), or None: fitted.

    ``given``: planes by id, each in the base frame of the terms that touch it (a plane or
    plane-point term's touches name it).

    Raises:
        InvalidArgumentError: A plane given that no plane term touches, touched from two base
            frames, or a term touching planes given and planes not.
    """
    if given is None:
        return [None] * len(data)
    planes = given_objects(given, PlaneContact())
    out: list[dict | None] = []
    bases: dict[str, set[str]] = {name: set() for name in planes}
    for chain, d in zip(chains, data, strict=True):
        touched = d.contacts if isinstance(getattr(d, "kind", None), _PLANES) else ()
        mine = [i for i in touched if i in planes]
        if mine and len(mine) < len(touched):
            other = next(i for i in touched if i not in planes)
            raise InvalidArgumentError(
                f"{d.source}: touches of plane '{mine[0]}', given, and of '{other}', not: give "
                f"every plane of a term, or none"
            )
        for name in mine:
            bases[name].add(chain.base_frame)
        out.append({i: planes[i] for i in mine} if mine else None)
    for name, frames in bases.items():
        if not frames:
            raise InvalidArgumentError(
                f"plane '{name}' is given, but no plane or plane-point term touches it"
            )
        if len(frames) > 1:
            raise InvalidArgumentError(
                f"plane '{name}' is given in one base frame, but is touched from "
                f"{' and '.join(sorted(frames))}"
            )
    return out
