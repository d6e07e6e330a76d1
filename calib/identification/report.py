"""Human-readable text for the CLI and notebooks: MDH tables and identifiability reports."""

from __future__ import annotations

import math

from ..core.words import counted
from ..kinematics.mdh import MDHModel
from ..kinematics.mimic import MimicJoint
from ..kinematics.tree_model import TreeMDH
from .contacts import Contact
from .identifiability import Identifiability
from .parameters import ROW_NAME, Kind
from .table import format_table

__all__ = [
    "analysis_text",
    "coupling_lines",
    "format_table",
    "mdh_table",
    "tree_table",
]

_STATUS = {"identifiable": "id", "regrouped": "reg", "zero": "0"}


def _num(x: float, digits: int = 4) -> str:
    """Fixed-point text without a negative zero."""
    text = f"{x:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def _row_cells(mdh: MDHModel | TreeMDH, k: int) -> list[str]:
    """beta, alpha, d, theta, r of row k; the joint variable q_k shown where it acts.

    A joint traversed backwards (sign -1) shows ``-qk``.
    """
    s = int(mdh.sigma[k])
    theta = _num(math.degrees(mdh.theta[k]), 3)
    r = _num(mdh.r[k])
    q = f"-q{k}" if isinstance(mdh, MDHModel) and mdh.sign[k] < 0 else f"q{k}"
    if s == 0:
        theta = q if abs(mdh.theta[k]) < 5e-7 else f"{q}{'+' if mdh.theta[k] > 0 else ''}{theta}"
    elif s == 1:
        r = q if abs(mdh.r[k]) < 5e-7 else f"{q}{'+' if mdh.r[k] > 0 else ''}{r}"
    beta, alpha = _num(math.degrees(mdh.beta[k]), 3), _num(math.degrees(mdh.alpha[k]), 3)
    return [beta, alpha, _num(mdh.d[k]), theta, r]


def _row_label(model: MDHModel | TreeMDH, k: int, frame: str = "") -> str:
    """Row k's URDF joint, or the fixed frame it stands for, in parentheses.

    ``(base)`` (row 0), ``(tool)`` (a chain's row n+1), ``(tool <name>)`` (a tree's); ``frame``
    follows base and a chain's tool (``" frame"``: ``(base frame)``).
    """
    if model.joint_names[k] is not None:
        return str(model.joint_names[k])
    if k == 0:
        return f"(base{frame})"
    if isinstance(model, MDHModel):
        return f"(tool{frame})"
    name = model.tool_frame_of(k)
    return f"(tool {name})" if name else f"(tool{frame})"


def mdh_table(mdh: MDHModel) -> str:
    """The MDH rows in degrees and metres, frame 0 to frame n+1."""
    header = ["j", "joint", "sigma", "beta[deg]", "alpha[deg]", "d[m]", "theta[deg]", "r[m]"]
    rows = []
    for k in range(mdh.n + 2):
        s = int(mdh.sigma[k])
        rows.append([str(k), _row_label(mdh, k), "fixed" if s < 0 else str(s), *_row_cells(mdh, k)])
    return format_table(header, rows)


def tree_table(model: TreeMDH) -> str:
    """The rows of a tree in degrees and metres: antecedent, gamma and b, then a chain's."""
    header = ["j", "a(j)", "joint", "sigma", "gamma[deg]", "b[m]"]
    header += ["beta[deg]", "alpha[deg]", "d[m]", "theta[deg]", "r[m]"]
    rows = []
    for k in range(len(model.sigma)):
        s = int(model.sigma[k])
        name = _row_label(model, k)
        gamma, b = _num(math.degrees(model.gamma[k]), 3), _num(model.b[k])
        fixed = "fixed" if s < 0 else str(s)
        rows.append([str(k), str(int(model.antecedent[k])), name, fixed, gamma, b])
        rows[-1] += _row_cells(model, k)
    return format_table(header, rows)


def _analysis_label(res: Identifiability, k: int) -> str:
    """Row k's joint in analyze's text, or the frame it stands for: ``(base frame)``, ...

    A contact's row 0 places its object (frame -1: the plane, the point or the pose held),
    not a base frame: ``(plane frame)``.
    """
    if k == 0 and isinstance(res.measurement, Contact):
        return f"({res.measurement.object_name} frame)"
    return _row_label(res.mdh, k, " frame")


def _status_table(res: Identifiability) -> str:
    """Table-2 style: per frame and parameter, id / reg / 0 (- where not in the set)."""
    kinds = [
        k
        for k in (Kind.GAMMA, Kind.B, Kind.BETA, Kind.ALPHA, Kind.D, Kind.THETA, Kind.R, Kind.Y)
        if any(p.kind is k for p in res.params.parameters)
    ]
    names = set(res.params.names)
    rows = []
    for k in range(len(res.mdh.sigma)):
        row = [str(k), _analysis_label(res, k)]
        for kind in kinds:
            name = f"{kind.value}{k}"
            row.append(_STATUS[res.status(name)] if name in names else "-")
        rows.append(row)
    return format_table(["j", "joint", *[k.value for k in kinds]], rows)


def _label(res: Identifiability, name: str) -> str:
    """The joint of a parameter's row (or the frame the row stands for): ``wrist_3_joint``."""
    row = ROW_NAME.fullmatch(name)
    return "" if row is None else _analysis_label(res, int(row.group(2)))


def _named(res: Identifiability, name: str) -> str:
    """A parameter and its row's joint or frame: ``theta6 (wrist_3_joint)``."""
    label = _label(res, name)
    return f"{name} {label if label.startswith('(') else f'({label})'}"


def _base_lines(res: Identifiability) -> list[str]:
    """Each base parameter, its row's joint (or frame), and what it stands for."""
    regrouping = res.regrouping()
    width = max((len(n) for n in regrouping), default=0)
    joints = {n: _label(res, n) for n in regrouping}
    jw = max((len(j) for j in joints.values()), default=0)
    return [f"  {n:>{width}} {joints[n]:<{jw}} = {e}" for n, e in regrouping.items()]


def analysis_text(res: Identifiability) -> str:
    """The full human report of ``calib analyze``."""
    d = res.to_dict()
    j = d["joints"]
    lines = [
        f"{res.robot}: {res.base_frame} -> {res.tool_frame}, {j['revolute']}R {j['prismatic']}P, "
        f"measure {res.measurement.label}"
        + (f" at marker {tuple(res.measurement.marker)} m" if any(res.measurement.marker) else "")
        + f", {res.params.label} set, {res.n_configs} configurations (seed {res.seed})",
        "",
        "Status of the standard parameters by MDH row j and its URDF joint"
        " (id identifiable, reg regrouped/eliminated, 0 no effect):",
        _status_table(res),
        "",
        f"Base parameters ({res.n_base}) with the joint of their row, and what they stand for:",
        *_base_lines(res),
    ]
    last, nxt = res.gap
    gap = (
        f"|R_bb| = {last:.3g}, next {nxt:.3g}"
        if nxt is not None
        else f"|R_bb| = {last:.3g}, full rank"
    )
    lines += [
        "",
        f"standard {res.n_standard}, base {res.n_base}, complete model {res.n_complete}, "
        f"theory {res.n_theory if res.n_theory is not None else 'n/a'}" + _theory_note(res),
        f"rank tolerance tau = {res.tolerance:.3g}; {gap}",
        *_tree_theory_lines(res),
    ]
    if res.snapped:
        lines.append(f"URDF round-off removed before the analysis: {'; '.join(res.snapped)}")
    lines += _mimic_lines(res)
    unseen = res.unseen
    if unseen:
        lines.append(f"a {res.measurement.label} contact can never identify:")
        lines += [f"  - {u}" for u in unseen]
    if res.zero:
        lines.append(f"no effect (not identifiable): {', '.join(_named(res, n) for n in res.zero)}")
    if res.missing:
        lines.append(
            f"incomplete: the {res.params.label} set misses "
            f"{counted(res.n_complete - res.n_base, 'error directions')} a complete model has:"
        )
        lines += [f"  - {m}" for m in res.missing]
    else:
        lines.append("complete: the set represents every error direction the measurement can see")
    return "\n".join(lines)


def _tree_theory_lines(res: Identifiability) -> list[str]:
    """For a tree: the theory's terms, each tool's chain alone, what sharing joints removes."""
    if not res.per_tool:
        return []
    sigma = res.mdh.sigma
    R, P, T = int(sum(sigma == 0)), int(sum(sigma == 1)), len(res.per_tool)
    per = 6 if res.measurement.n_rows == 6 else 3
    theory = (
        f"4R + 2P + {per}T = {4 * R + 2 * P + per * T} for R={R}, P={P}, T={T}"
        + (", before points on axes" if res.on_axes and per == 3 else "")
        if not res.mimic
        else f"4R + 2P + {per}T is for independent joints: n/a with coupled joints"
    )
    lines = [
        f"tree of {T} tools: every joint counted once, each tool {per} ({theory})",
        "  each tool's chain alone: "
        + ", ".join(f"{name} {'n/a' if c is None else c}" for name, c in res.per_tool),
    ]
    counts = [c for _, c in res.per_tool]
    if res.n_theory is not None and None not in counts:
        total = sum(counts)  # type: ignore[arg-type]
        lines.append(
            f"  the chains alone sum to {total}; the tree has {total - res.n_theory} fewer: a "
            f"joint shared by k tools is counted k times in the sum (4 per revolute, 2 per "
            f"prismatic joint), once in the tree"
        )
    return lines


def _mimic_expression(mj: MimicJoint) -> str:
    """``joint3 = -1 joint2 + 0.1``: how a mimic joint follows its master."""
    sign = "-" if mj.offset < 0 else "+"
    return f"{mj.name} = {mj.multiplier:g} {mj.master} {sign} {abs(mj.offset):g}"


def coupling_lines(mimic: tuple[MimicJoint, ...]) -> list[str]:
    """The mimic joints of a chain, one line each (none for a chain without them)."""
    if not mimic:
        return []
    return [
        "coupled joints (URDF <mimic>): their positions are computed, q_k of row k:",
        *(f"  row {mj.joint + 1}: {_mimic_expression(mj)}" for mj in mimic),
    ]


def _mimic_lines(res: Identifiability) -> list[str]:
    """What the analysis says about coupled joints (none for a chain without mimic joints)."""
    if not res.mimic:
        return []
    out = [
        "coupled joints (URDF <mimic>; the theory is for independent joints): the offset of "
        "each mimic expression and the joint offset of its row are one parameter"
    ]
    offsets = res.mimic_offsets()
    for mj in res.mimic:
        k = mj.joint + 1
        with_ = f"no effect, as {offsets[k]}" if offsets[k] in res.zero else offsets[k]
        out.append(f"  offset{k} of {_mimic_expression(mj)}: with {with_}")
    return out


def _theory_note(res: Identifiability) -> str:
    """The points on axes, else why there is no theory (``n/a (prismatic first joint)``).

    A contact without a theory: its kind's reason (a tip on the last axis is not why).
    """
    note = "" if res.measurement.is_contact and res.n_theory is None else _axes_note(res)
    if note or res.n_theory is not None or not res.theory_note:
        return note
    return f" ({res.theory_note})"


def _axes_note(res: Identifiability) -> str:
    if res.measurement.row_names != ("x", "y", "z") or not res.on_axes:
        return ""
    if res.per_tool:
        if res.n_theory is None:
            return " (points on joint axes the formula does not cover)"
        return " (points on the last axis of their tools: 2 fewer per such joint)"
    if res.on_axes == (res.mdh.n,):
        return " (point on the last axis: 2 fewer)"
    axes = ", ".join(str(k) for k in res.on_axes)
    return f" (point on axes {axes}: the formula covers the last axis only)"
