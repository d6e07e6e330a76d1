"""A pixel term's part of a result: its camera, intrinsics, targets and errors (px, mm)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..exceptions import DataError
from ..kinematics.robot import Chain
from .contact_result import GapStats, TermPart, part_stats, row_stats, units
from .diagnosis import NOISE_FACTOR, suspect
from .outliers import Outlier
from .pixel_chain import PixelKind, PixelPart, PixelTermState, camera_step
from .report import parameter_entries, pose_dict

__all__ = [
    "DETECTOR_PX",
    "EXPECTED_PX",
    "LENS_GAIN",
    "LENS_PX",
    "REFUSED_PX",
    "PixelChain",
    "check_fitted_pixels",
    "pixel_result",
]

EXPECTED_PX = 3.0
"""Largest calibrated reprojection error (RMS, training or held out) a camera's pixels are
expected to leave [px]; beyond, the fit is warned about.
Rationale and measurements: docs/developers/engine.md#expected_px"""

DETECTOR_PX = 1.0
"""A corner detector's largest noise (RMS) [px]: a fraction of a pixel (the simulations use
0.2 to 0.5 px); the pixels' noise, as no option gives it."""

LENS_GAIN = 0.9
"""Fitting the intrinsics too would leave under this fraction of the training reprojection
error (RMS): the fit hints at them (with :data:`LENS_PX`).
Rationale and measurements: docs/developers/engine.md#lens_gain"""

LENS_PX = 0.1
"""Reprojection error [px RMS] the intrinsics must explain (the quadratic difference of the
errors before and after fitting them) for the fit to hint at them: a tenth of a pixel.
Measurements: as ``LENS_GAIN``."""

REFUSED_PX = NOISE_FACTOR * DETECTOR_PX
"""Calibrated reprojection error (RMS) [px] over which pixels that the registration and the
calibrated model both miss by over ``SUSPECT`` at the target are refused
(:func:`check_fitted_pixels`).
Rationale and measurements: docs/developers/engine.md#refused_px"""


def _errors(state: PixelTermState, part: PixelPart) -> tuple[GapStats, dict]:
    """The rows' errors in mm at the target (u and v times the weight), and in pixels (RMS, max)."""
    e = state.pixel_errors(part)  # [px]
    r = np.linalg.norm(e, axis=1)
    rms, top = float(np.sqrt(np.mean(r**2))), float(np.max(r, initial=0.0))
    pixels = {"reprojection_rms_px": rms, "reprojection_max_px": top}
    return row_stats(e * state.weight, state.kind, np.ones(2)), pixels


@dataclass(frozen=True, eq=False)
class PixelChain(TermPart):
    """A pixel term's part of the result (a camera on a link seeing a target on a tool).

    ``name``: the camera's (its link in the calibrated URDF); ``stats``: errors in mm at the
    target by part (``train``, ``train_registration``, ``held_out``...); ``pixels``: the same
    parts' reprojection errors [px]; ``registered``, ``state``: its registration on the nominal
    robot and its fitted state (camera, target, lens); ``parameters``: its unknowns' report
    entries (changes from the registration); ``outliers``: its rows set aside;
    ``postures``: the postures of ``train`` and ``held_out`` (a row is a pixel);
    ``lens_px``: the training reprojection error [px RMS] were the intrinsics fitted too
    (:func:`!lens_rms`; None: they were).
    """

    chain: Chain
    source: str
    name: str
    registered: PixelTermState
    state: PixelTermState
    stats: dict[str, GapStats]
    pixels: dict[str, dict]
    held_source: str | None = None
    held_rows: tuple[int, ...] | None = None
    parameters: tuple[dict, ...] = ()
    outliers: tuple[Outlier, ...] = ()
    postures: dict[str, int] = field(default_factory=dict)
    lens_px: float | None = None
    rows: ClassVar[str] = "pixels"

    def camera_dict(self) -> dict:
        """The report's ``frames.cameras`` entry: link, pose, intrinsics [px]."""
        lens = self.state.lens
        return {
            "link": self.chain.base_frame,
            **(pose_dict(self.state.camera) or {}),
            "intrinsics": dict(zip(lens.parameter_names, map(float, lens.parameters), strict=True)),
            "weight_m_per_px": self.state.weight,
        }

    @property
    def kind(self) -> PixelKind:
        """The term's layout (its rows ``u, v``, its unknowns' names)."""
        return self.state.kind

    def errors(self) -> dict:
        """``errors.terms``: train and held out, mm at the target and px (format 3).

        Each error entry's ``configs`` counts postures, its ``pixels`` the pixels.
        """
        out = super().errors()
        for part in ("train", "held_out"):
            if out[part] is not None:
                for key in ("registration", "calibrated", "urdf"):
                    entry = out[part][key]
                    counts = {"configs": self.postures[part], "pixels": entry.pop("configs")}
                    out[part][key] = {**counts, **entry}
                out[part]["pixels"] = {
                    "registration": self.pixels[f"{part}_registration"],
                    "calibrated": self.pixels[part],
                }
        return out

    def configs(self) -> int:
        """Its fitted postures (the report's ``terms[k].configs``; its pixels are more)."""
        return self.postures["train"]

    def warnings(self) -> list[str]:
        """A calibrated reprojection error above :data:`EXPECTED_PX` (RMS), said once.

        Under it, an error the intrinsics would explain (:data:`LENS_GAIN`, :data:`LENS_PX`)
        when they were not fitted.
        """
        worst = max(
            (k for k in ("train", "held_out") if k in self.pixels),
            key=lambda k: self.pixels[k]["reprojection_rms_px"],
        )
        rms = self.pixels[worst]["reprojection_rms_px"]
        if not rms > EXPECTED_PX:
            return self._lens_hint()
        fix = "" if self.state.what.intrinsics else ", or fit them: Unknowns(intrinsics=True)"
        return [
            f"camera {self.name}: the calibrated reprojection error is {rms:.1f} px RMS "
            f"({worst.replace('_', '-')}), far above a detector's noise (over "
            f"{EXPECTED_PX:g} px): check its intrinsics (image width and height swapped, the "
            f"focal length, the principal point){fix}"
        ]

    def _lens_hint(self) -> list[str]:
        """The intrinsics hinted at: fitted too, they would lower the error much."""
        now, fitted = self.pixels["train"]["reprojection_rms_px"], self.lens_px
        if fitted is None or not (fitted < LENS_GAIN * now and now**2 - fitted**2 > LENS_PX**2):
            return []
        return [
            f"camera {self.name}: fitting its intrinsics too would lower the reprojection "
            f"error from {now:.3g} to {fitted:.3g} px RMS or less (train, to first order): check "
            f"them (the focal length, the principal point), or fit them: Unknowns(intrinsics=True)"
        ]

    def heading(self) -> str:
        """Its camera, its rows' units and its reprojection errors [px]."""
        px = ", ".join(
            f"{k.replace('_', ' ')} {self.pixels[k]['reprojection_rms_px']:.3g}"
            for k in ("train", "held_out")
            if k in self.pixels
        )
        what = f"{units(self.kind)} at the target; reprojection RMS [px]"
        return f"camera {self.name} (errors: {what}: {px})"

    def _own(self) -> dict:
        """Its camera, targets and errors (mm and px)."""
        return {
            "camera": self.name,
            **self.camera_dict(),
            "targets": self.state.target.tolist(),
            "errors": {k: v.to_dict() for k, v in self.stats.items()},
            "pixels": self.pixels,
        }


def pixel_result(chain, train, held, registered, state, x, std, term: int) -> PixelChain:
    """A pixel term's part: its errors (mm and px), and its unknowns' report entries.

    ``x``, ``std``: its own unknowns' changes from ``registered`` and their std; ``term``: its
    number (1-based) in its unknowns' names.
    """
    found = part_stats(_errors, registered, state, train, held)
    stats, pixels = {k: v[0] for k, v in found.items()}, {k: v[1] for k, v in found.items()}
    names = [f"term{term}.{n}" for n in state.kind.names()]
    entries = parameter_entries(names, x, std, ())
    name = train.data.camera.name
    parts = {"train": train} if held is None else {"train": train, "held_out": held}
    postures = {k: len(np.unique(p.q, axis=0)) for k, p in parts.items()}
    return PixelChain(
        chain,
        train.source,
        name,
        registered,
        state,
        stats,
        pixels,
        parameters=tuple(entries),
        postures=postures,
        lens_px=lens_rms(state, train),
    )


def lens_rms(state: PixelTermState, part: PixelPart) -> float | None:
    """The reprojection error of ``part`` [px RMS] were the intrinsics fitted too, or None.

    To first order, with the camera's placement fitted again beside them: the rows' errors
    are already at the least squares of every unknown fitted, the joints' too (fitted again,
    they could only lower it further). None: the intrinsics were fitted, or no row.
    """
    if state.what.intrinsics or part.m == 0:
        return None
    p_cam = state.seen(part)
    seen = state.lens.projection(p_cam, derivatives=True)
    by = np.concatenate([np.asarray(seen.d_point) @ camera_step(p_cam), seen.d_parameters], 2)
    A, e = by.reshape(2 * part.m, -1), (seen.pixels - part.rows.pixels).ravel()
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(e))):
        return None
    r = e - A @ np.linalg.lstsq(A, e, rcond=None)[0]
    return float(np.sqrt(r @ r / part.m))


def check_fitted_pixels(part: PixelChain) -> None:
    """Stop on pixels the calibrated camera and robot still miss absurdly.

    Raises:
        DataError: Registered and calibrated both suspect at the target
            (:func:`~.diagnosis.suspect`), and over :data:`REFUSED_PX`.
    """
    keys = ("train_registration", "train")
    registered, missed = (1e-3 * part.stats[k].length_rms_mm for k in keys)  # [m at the target]
    before, after = (part.pixels[k]["reprojection_rms_px"] for k in keys)
    if suspect(registered, None) and suspect(missed, None) and after > REFUSED_PX:
        fix = "" if part.state.what.intrinsics else ", or fit them: Unknowns(intrinsics=True)"
        raise DataError(
            part.source,
            f"the pixels do not match camera {part.name} and {part.chain.base_frame} -> "
            f"{part.chain.tool_frame}: the calibrated reprojection error is {after:.4g} px RMS "
            f"(registered: {before:.4g} px): the camera on another link than "
            f"{part.chain.base_frame} (its chain has a joint that does not move the camera, or "
            f"misses one that does), another camera's images or intrinsics (check the "
            f"camera's{fix}), another robot's postures, or another target?",
        )
