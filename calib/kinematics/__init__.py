"""The robot's geometry: URDF reading and writing, chains, trees, mimic joints, MDH, SO(3).

Reads a URDF (:mod:`.urdf_xml`, :mod:`.urdf_model`) into a chain (:mod:`.robot`, with the
joints and frames of the Pinocchio model in :mod:`.frames`) or a tree (:mod:`.tree`), converts
them to modified DH (:mod:`.mdh`, :mod:`.tree_model`), and writes a calibrated URDF back
(:mod:`.urdf_export`, :mod:`.urdf_links`, :mod:`.tree_export`, with the joint compliance of
:mod:`.elastic`). :mod:`.catalog` lists the robots calib ships.

May import: only the bottom modules (:mod:`calib.core`: checks, choices, fileio, lazy; and
:mod:`calib.exceptions`).
"""

__all__: list[str] = []
