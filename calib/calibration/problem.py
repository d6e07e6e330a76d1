"""A calibration problem: the terms recorded on one robot, and the options of one fit.

``calibrate(Problem((Term(left_arm, left_touches), Term(right_arm, right_touches))))``;
``calibrate(chain, data, **options)`` is the problem of one term. Terms, shapes and the
options of each: docs/developers/engine.md#problem
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import KW_ONLY, dataclass, fields

import numpy as np

from ..exceptions import InvalidArgumentError
from ..identification.contacts import FixedPoseContact
from ..kinematics.robot import Chain, check_robot
from ..kinematics.tree import Tree
from ..measurements.contact_campaign import ContactData
from ..measurements.contact_objects import term_planes
from ..measurements.data import Measurements
from ..measurements.unseen import check_every_marker_seen
from .options import APPLIES, SHAPE_LABELS, Options, checked_init
from .pixel_chain import PixelData

__all__ = ["Problem", "Term", "check_pose_weighed", "check_weighed"]


_GUESS = "a term's guess= is calibrate's marker= (measurements) or contact= (touches)"


@checked_init(
    "Term takes the robot and the data by position, validate= and guess= by name",
    {"marker": _GUESS, "markers": _GUESS, "contact": _GUESS},
)
@dataclass(frozen=True, eq=False)
class Term:
    """One chain (or tree) of the robot and what was recorded on it.

    Attributes:
        robot: The nominal chain or tree (:func:`~calib.load_robot`); its
            base frame is where the data are expressed (an instrument's frame is registered,
            a frame of the robot measures itself), its tool what is measured or touches.
        data: Measurements (position, pose, several markers), touches
            (:class:`~calib.measurements.contact_campaign.ContactData`, any contact kind) or
            a camera's pixels (:class:`~.pixel_chain.PixelData`: always a term of the joint
            fit, ``shape`` ``chains``, even alone).
        validate: Data of the same kind at other postures, scored and never fitted, or None.
        guess: Guess of each measured point in the tool frame, 3 numbers or ``(K, 3)`` [m]
            (measurements), or of the contact frame in the tool frame, ``(4, 4)`` or
            ``X Y Z [RX RY RZ]`` [m, rad] (touches); None: the tool frame.
    """

    robot: Chain | Tree
    data: Measurements | ContactData | PixelData
    validate: Measurements | ContactData | PixelData | None = None
    guess: object = None

    def __post_init__(self) -> None:
        check_robot(self.robot, "a term's robot")
        if not isinstance(self.data, Measurements | ContactData | PixelData):
            raise InvalidArgumentError(
                "a term's data must be Measurements, ContactData or PixelData "
                f"(read_measurements, read_contacts), got {type(self.data).__name__}"
            )
        if isinstance(self.data, ContactData | PixelData) and self.robot.is_tree:
            raise InvalidArgumentError(
                "touches are recorded on a chain (one base, one tool), got a tree: give one "
                "term per chain"
            )
        if isinstance(self.data, Measurements) and self.data.partial:  # each marker fitted
            check_every_marker_seen(
                self.data.position, self.data.position_columns, self.data.source
            )
        if self.validate is not None and type(self.validate) is not type(self.data):
            raise InvalidArgumentError(
                f"a term's validation data must be {type(self.data).__name__} like its data, "
                f"got {type(self.validate).__name__}"
            )

    @property
    def touches(self) -> bool:
        """Whether the term's data are touches (no instrument, the joints alone)."""
        return isinstance(self.data, ContactData)

    @property
    def kind(self) -> str:
        """The data's kind, ``position``, ``pose``, ``markers``, or a contact kind's label."""
        if isinstance(self.data, ContactData):
            return self.data.kind.label
        if isinstance(self.data, PixelData):
            return "pixels"
        if self.data.quaternion is not None:
            return "pose"
        return "position" if self.data.position.shape[1] == 3 else "markers"

    def __repr__(self) -> str:
        tools = ", ".join(self.robot.tool_frames)
        return f"Term({self.robot.base_frame} -> {tools}: {self.data.m} rows of {self.kind})"


@checked_init(
    "Problem takes its terms by position, as one tuple, and its options by name: "
    "Problem((term1, term2), params='complete')",
    {"folds": "K folds: calib.cross_validate(problem, folds=K)"},
)
@dataclass(frozen=True)
class Problem(Options):
    """Terms of one robot fitted together, and the options of the fit.

    Its options are :class:`~.options.Options`'s fields, by name (checked when made; a
    holdout not with a term's validation data), and the joint fit's own:
    ``Problem((Term(arm, touches),), params="complete")``.

    Attributes:
        terms: One or more :class:`Term` of one URDF.
        params: Parameter level (``auto``, ``frames``, ``offsets``, ``paper``, ``complete``;
            default: ``auto``, a tree's ``complete``).
        fix: Parameter names (or ``frame``, ``markers``, ``tool``) held at their start.
        free: Parameter names (a compliance ``c1``.. included) always fitted.
        elastic: Fit joint compliance under gravity (default: no, unless ``free`` names one).
        loss: ``linear``, ``soft_l1`` or ``huber`` (scale ``noise_mm``).
        noise_mm: Instrument noise [mm] (default: unknown).
        orientation_weight: Weight of the orientation rows [m/rad] (default: estimated).
        max_iterations: Most residual evaluations of each solver run.
        holdout: Fraction of each term's rows set aside (seeded); not with validation data.
        seed: Seed of the holdout draw and of the generic configurations of the rank checks.
        shared_planes: Terms of one base frame whose touches name the same plane touch one
            plane (default: a plane per term).
        pose_weight: Factor of the fixed-pose (closed loop) terms' rows against the others'.
        known_planes: Planes given, by the id the touches name them, each in the base frame of
            the terms that touch it: a frame ``(4, 4)`` (z its normal) or a point and a normal
            ``(x, y, z, nx, ny, nz)`` [m] (:mod:`!calib.measurements.contact_objects`). Held,
            not fitted: their terms fit the contact frame's height along the normal instead
            (default: every plane fitted).
    """

    terms: tuple[Term, ...]
    _: KW_ONLY
    shared_planes: bool = False
    pose_weight: float = 1.0
    known_planes: Mapping | None = None

    def __post_init__(self) -> None:
        terms = self.terms
        if isinstance(terms, Term):
            terms = (terms,)
        if not isinstance(terms, tuple | list) or not terms:
            raise InvalidArgumentError("a problem needs at least one Term")
        bad = [t for t in terms if not isinstance(t, Term)]
        if bad:
            raise InvalidArgumentError(f"a problem's terms must be Term, got {bad[0]!r:.60}")
        object.__setattr__(self, "terms", tuple(terms))
        urdfs = {str(t.robot.urdf_resolved) for t in self.terms}  # the files, not their names
        if len(urdfs) > 1:
            raise InvalidArgumentError(
                f"the terms of one problem are chains of one URDF, got {len(urdfs)}: "
                f"{', '.join(sorted(urdfs))}"
            )
        super().__post_init__()  # the values, checked once (the level by the model of the shape)
        if self.holdout > 0 and any(t.validate is not None for t in self.terms):
            raise InvalidArgumentError("give a validation file or a holdout fraction, not both")
        self._check_applicable()
        term_planes([t.robot for t in self.terms], [t.data for t in self.terms], self.known_planes)

    def options(self) -> Options:
        """The problem's options alone, as one value (its terms and the joint fit's left)."""
        return Options(**{f.name: getattr(self, f.name) for f in fields(Options)})

    @property
    def shape(self) -> str:
        """``chain``, ``tree``, ``contacts`` (one term each), ``chains`` (several, or pixels)."""
        if len(self.terms) > 1 or isinstance(self.terms[0].data, PixelData):
            return "chains"
        term = self.terms[0]
        if term.touches:
            return "contacts"
        return "tree" if term.robot.is_tree else "chain"

    def _check_applicable(self) -> None:
        """Refuse an option of :data:`~.options.APPLIES` given where it does not apply."""
        shape = self.shape
        defaults = {f.name: f.default for f in fields(self)}
        for name, shapes in APPLIES.items():
            if shape in shapes or name not in defaults:
                continue
            value = getattr(self, name)
            if value is None or value is False or _same(value, defaults[name]):
                continue
            where = " or ".join(SHAPE_LABELS[s] for s in shapes)
            raise InvalidArgumentError(f"{name} is for {where}, not {SHAPE_LABELS[shape]}")
        check_weighed(self.orientation_weight, [t.data for t in self.terms])
        if shape == "chains":
            self._check_terms()
            check_pose_weighed(self.pose_weight, [t.data for t in self.terms])

    def _check_terms(self) -> None:
        """Several terms: chains (no tree), and one contact guess for the touching ones."""
        if any(t.robot.is_tree for t in self.terms):
            raise InvalidArgumentError(
                "the terms of a joint fit are chains (one base, one tool each), got a tree"
            )
        guesses = [t.guess for t in self.terms if t.touches and t.guess is not None]
        if any(not _same(g, guesses[0]) for g in guesses[1:]):
            raise InvalidArgumentError(
                "the touching terms of a joint fit share one contact frame guess: give the same "
                "guess to each (or none)"
            )
        if any(t.guess is not None for t in self.terms if not t.touches):
            raise InvalidArgumentError(
                "a measured term of a joint fit takes no guess: its markers are registered"
            )


def check_weighed(weight: float | None, data: Sequence) -> None:
    """Refuse an orientation weight [m/rad] where no term's data have angle rows to weigh.

    Raises:
        InvalidArgumentError: ``weight`` is not None and no term has angle rows (orientations,
            tilts).
    """
    if weight is None:
        return
    for d in data:
        if isinstance(d, Measurements) and d.quaternion is not None:
            return
        if isinstance(d, ContactData) and any(d.kind.angular):
            return
    raise InvalidArgumentError(
        "orientation_weight weighs orientation or tilt rows: no term has any (positions, "
        "plane-point or fixed-point touches, image points)"
    )


def check_pose_weighed(weight: float, data: Sequence) -> None:
    """Refuse a ``pose_weight`` other than 1 where no term's data are fixed-pose touches.

    Raises:
        InvalidArgumentError: It would weigh nothing (the command line's ``--pose-weight``
            without ``--loop`` or ``--term fixed-pose``).
    """
    if weight == 1.0 or any(isinstance(getattr(d, "kind", None), FixedPoseContact) for d in data):
        return
    raise InvalidArgumentError(
        "pose_weight weighs the rows of fixed-pose (closed loop) terms: no term is one"
    )


def _same(a, b) -> bool:
    """Whether two option values are equal (numbers, tuples, arrays)."""
    try:
        return bool(np.array_equal(np.asarray(a, dtype=object), np.asarray(b, dtype=object)))
    except ValueError:  # ragged
        return a == b
