"""Write a calibrated tree back as a URDF: the origins of every branch, nothing else.

As for a chain (:mod:`.urdf_export`): ``moved_k = T_k_cal(0) T_k_nom(0)^-1`` moves what
MDH frame k carries; the new pose of URDF joint j is ``moved_{row j} T_urdf_j_nom``, and its
new origin is the inverse pose of its parent link (carried rigidly by the antecedent joint)
times it. In a tree a frame k is the frame of its own row only on a path through its first
child (on another branch the path model merges that branch's gamma and b into row k), so
``moved_k`` is taken there. The first joint on the base keeps its placement; the base part
of the calibration is the measurement-frame -> base transform (:func:`tree_measurement_to_base`),
and the other joints on the base are placed relative to it.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..core.fileio import check_outputs, write_atomic
from ..exceptions import InvalidArgumentError
from .mdh import frames_at_zero
from .tree import Tree
from .tree_model import TreeMDH
from .urdf_export import (
    NominalPoses,
    child_link,
    edited_joints,
    parent_link,
    read_urdf_source,
    set_origin,
    spliced,
    xml_layout,
)
from .urdf_links import add_marker_links

__all__ = ["calibrated_tree_urdf", "tree_measurement_to_base", "write_calibrated_tree_urdf"]


def moved_frames(nominal: TreeMDH, calibrated: TreeMDH) -> dict[int, np.ndarray]:
    """``T_k_cal(0) T_k_nom(0)^-1`` of every row k of a tree (frame -1 = base)."""
    if not (isinstance(nominal, TreeMDH) and isinstance(calibrated, TreeMDH)) or not (
        np.array_equal(nominal.antecedent, calibrated.antecedent)
    ):
        raise InvalidArgumentError("two models of the same tree are needed (TreeMDH)")
    moved: dict[int, np.ndarray] = {}
    for t in range(nominal.n_tools):
        rows = nominal.path_rows(t)
        Fn = frames_at_zero(nominal.path_model(t))
        Fc = frames_at_zero(calibrated.path_model(t))
        for i, k in enumerate(int(r) for r in rows):
            last = i + 1 == len(rows)
            if k not in moved and (last or nominal.first_child(int(rows[i + 1]))):
                moved[k] = Fc[i] @ np.linalg.inv(Fn[i])
    return moved


def tree_measurement_to_base(nominal: TreeMDH, calibrated: TreeMDH) -> np.ndarray:
    """Pose of the calibrated URDF's base frame in frame -1 of ``calibrated`` ``(4, 4)``.

    It is the motion of the first joint on the base: ``T @ FK_urdf_cal(q) ==`` the
    calibrated model's forward kinematics, for every tool.
    """
    first = int(np.flatnonzero(nominal.antecedent == 0)[0])
    return moved_frames(nominal, calibrated)[first]


def calibrated_tree_urdf(
    tree: Tree, nominal: TreeMDH, calibrated: TreeMDH, markers: np.ndarray | None = None
) -> bytes:
    """The tree's URDF file with the calibrated placements of every joint and tool.

    ``markers``: each tool's measured point in its frame ``(T, 3)`` [m], written as a fixed
    link ``<tool>_marker1`` under the tool link (default: none).

    Raises:
        InvalidArgumentError: The models are not models of the tree.
        URDFError: The original file cannot be read.
        CalibError: A tool frame is not carried by a fixed joint, or the file does not
            match the tree.
    """
    moved = moved_frames(nominal, calibrated)
    if not isinstance(tree, Tree) or nominal.n != tree.n or nominal.n_tools != tree.n_tools:
        raise InvalidArgumentError("calibrated_tree_urdf takes a Tree and two models of it")
    base = tree_measurement_to_base(nominal, calibrated)
    raw, root = read_urdf_source(tree.chains[0])
    start, stop = xml_layout(raw, str(tree.urdf_path))
    poses = NominalPoses(tree.chains[0])
    nom_joint = [poses.joint(jid) for jid in tree.joint_ids]

    def carried(row: int, link: str) -> np.ndarray:
        """New pose of a link rigidly carried by row ``row`` (0: the base link)."""
        return (base if row == 0 else moved[row]) @ poses.link(link)

    for t, chain in enumerate(tree.chains):
        joints, tool_joint = edited_joints(root, chain)
        tool_row = nominal.tool_rows[t]
        tool_new = moved[tool_row] @ poses.link(child_link(tool_joint))
        parent = carried(int(nominal.antecedent[tool_row]), parent_link(tool_joint))
        set_origin(tool_joint, np.linalg.inv(parent) @ tool_new)
        for j in tree.paths[t]:
            joint = joints[tree.joint_names[j]]
            new = moved[j + 1] @ nom_joint[j]
            parent = carried(int(nominal.antecedent[j + 1]), parent_link(joint))
            set_origin(joint, np.linalg.inv(parent) @ new)
        if markers is not None:
            add_marker_links(root, chain.tool_frame, child_link(tool_joint), markers[t : t + 1])
    return spliced(raw, root, start, stop)


def write_calibrated_tree_urdf(
    path: str | Path, tree: Tree, nominal: TreeMDH, calibrated: TreeMDH
) -> None:
    """Write :func:`calibrated_tree_urdf` atomically (never over the nominal URDF)."""
    if not isinstance(path, str | os.PathLike):
        raise InvalidArgumentError(f"path must be a file path, got {path!r:.60}")
    check_outputs({"path": path}, {"the nominal URDF": tree.urdf_resolved})
    write_atomic(path, calibrated_tree_urdf(tree, nominal, calibrated))
