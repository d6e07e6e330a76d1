"""The one place where a measure's name becomes a measurement kind (:func:`kind_of`)."""

from __future__ import annotations

from ..core.checks import shown
from ..exceptions import InvalidArgumentError
from .contacts import contact_kind
from .measures import CONTACT_NAMES, MeasureKind, Measurement, checked_marker


def kind_of(measure: str | MeasureKind = "pose", marker=None) -> MeasureKind:
    """The measurement kind a name stands for: the one place where names are read.

    Args:
        measure: ``pose``, ``position``, comma-separated rows (``x,y,rz``), a contact
            (``plane``, ``plane-point``, ``fixed-point``, ``fixed-pose``), or a kind (returned
            as is when no marker is given).
        marker: Measured point in the tool frame, 3 numbers [m] (instrument kinds only).

    Raises:
        InvalidArgumentError: Unknown name, a bad marker, or a marker with a contact.
    """
    if isinstance(measure, MeasureKind) and not isinstance(measure, str):
        if marker is not None and tuple(checked_marker(marker)) != tuple(measure.marker):
            raise InvalidArgumentError("give the marker in the measurement kind, not beside it")
        return measure
    if not isinstance(measure, str):
        raise InvalidArgumentError(f"a measure is a name or a kind, got {shown(measure)}")
    if measure in CONTACT_NAMES:
        if marker is not None and any(checked_marker(marker)):
            raise InvalidArgumentError(
                f"a {measure} contact measures no point: give no marker (the contact frame is "
                f"the tool frame)"
            )
        return contact_kind(measure)
    try:
        return Measurement.of(measure, marker)
    except InvalidArgumentError as exc:
        if str(exc).startswith("unknown measure"):
            raise InvalidArgumentError(
                f"{exc}, or a contact ({', '.join(CONTACT_NAMES)})"
            ) from None
        raise


def campaign_kind(measure: str | MeasureKind, marker=None, contacts: str = "") -> Measurement:
    """A kind a measured campaign can hold: the pose or the position of a point.

    Args:
        measure: The measure's name or kind (:func:`kind_of`).
        marker: Measured point in the tool frame, 3 numbers [m].
        contacts: What takes a contact instead, said after the error (e.g. ``"
            (touches: calib.simulate_contacts)"``).

    Raises:
        InvalidArgumentError: Another kind (rows, a contact) or an unknown name.
    """
    kind = kind_of(measure, marker)
    if kind.label in CONTACT_NAMES:
        raise InvalidArgumentError(
            f"a {kind.label} contact is not a measured campaign: choose pose or position{contacts}"
        )
    if not (isinstance(kind, Measurement) and kind.is_campaign):
        raise InvalidArgumentError(f"unknown measure '{kind.label}': choose pose or position")
    return kind


__all__ = ["campaign_kind", "kind_of"]
