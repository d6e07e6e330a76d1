"""The robot catalog (``models/catalog.toml``) and the URDF files it points to."""

from __future__ import annotations

import contextlib
import functools
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from ..exceptions import CalibError, RobotNotFoundError

__all__ = [
    "ERD_PREFIX",
    "Catalog",
    "CatalogEntry",
    "catalog",
    "catalog_entry",
    "catalog_files",
    "catalog_groups",
    "erd_robots_dir",
    "installed_dirs",
    "models_dir",
    "resolve_urdf",
    "shipped_urdf",
]

ERD_PREFIX = "erd:"
"""Prefix of a catalog URDF that lives in example-robot-data's ``robots/`` folder."""

_ERD_ROBOTS = "share/example-robot-data/robots/"


@dataclass(frozen=True)
class CatalogEntry:
    """One named serial chain, or tree of chains, of the catalog.

    Attributes:
        name: Short identifier used on the command line (``ur5``).
        urdf: ``erd:<path>`` inside example-robot-data, or a file name inside ``models/``.
        base: Name of the base frame (frame -1 of the chain).
        tool: Name of the tool frame (frame n+1 of the chain), or the names of the tools of a
            tree (a list in the catalog file, at least two).
        description: One line for ``calib list``.
        expect_error: Why the chain cannot be analysed, when it is known not to be.
    """

    name: str
    urdf: str
    base: str
    tool: str | tuple[str, ...]
    description: str
    expect_error: str | None = None

    def __post_init__(self) -> None:
        if isinstance(self.tool, list | tuple):
            if len(self.tool) < 2 or not all(isinstance(t, str) for t in self.tool):
                raise CalibError(f"catalog entry '{self.name}': a tool list has 2 or more names")
            object.__setattr__(self, "tool", tuple(self.tool))

    @property
    def tools(self) -> tuple[str, ...]:
        """The tool frame names: one for a chain, several for a tree."""
        return self.tool if isinstance(self.tool, tuple) else (self.tool,)

    @property
    def is_tree(self) -> bool:
        """True when the entry names several tools (a tree, see :func:`calib.load_robot`)."""
        return isinstance(self.tool, tuple)

    @property
    def path(self) -> Path:
        """Absolute path of the URDF file."""
        return resolve_urdf(self.urdf)


def models_dir() -> Path:
    """The folder holding the catalog and the project's own URDFs (installed or in-tree).

    The ``models/`` folder of the calib package (a wheel) or of the source tree (an editable
    install) when it is there: importing :mod:`importlib.resources` costs a start of ``calib``
    10 ms or more. Else where :mod:`importlib.resources` finds ``calib.models``.
    """
    here = Path(__file__).parent.parent  # calib/ (this module is in calib/kinematics/)
    if (here / "models" / "catalog.toml").is_file():
        return here / "models"
    tree = here.parent
    if (tree / "pyproject.toml").is_file() and (tree / "models" / "catalog.toml").is_file():
        return tree / "models"
    import importlib.resources

    return Path(str(importlib.resources.files("calib.models")))


@functools.cache
def erd_robots_dir() -> Path:
    """Locate example-robot-data's ``robots/`` folder through the installed distribution.

    The distribution's ``RECORD`` is read directly when its ``.dist-info`` folder is found on
    ``sys.path`` (importing :mod:`importlib.metadata` and listing the files through it costs
    a start of ``calib analyze`` 50 ms or more); otherwise through :mod:`importlib.metadata`.

    Raises:
        CalibError: example-robot-data is not installed or ships no robots folder.
    """
    found = _erd_robots_from_record()
    if found is not None:
        return found
    import importlib.metadata  # imported when needed (slow): ``calib list`` goes without

    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError as exc:
        raise CalibError(
            "example-robot-data is not installed (pip install example-robot-data)"
        ) from exc
    for f in dist.files or ():
        s = f.as_posix()
        i = s.find(_ERD_ROBOTS)
        if i >= 0:
            return Path(str(dist.locate_file(s[: i + len(_ERD_ROBOTS)])))
    raise CalibError("example-robot-data is installed but ships no share/example-robot-data/robots")


def _erd_robots_from_record() -> Path | None:
    """The robots folder of example-robot-data's ``RECORD``, read directly, or None.

    The first ``example_robot_data-*.dist-info`` on ``sys.path``: the distribution
    :mod:`importlib.metadata` would find.
    """
    for entry in sys.path:
        with contextlib.suppress(OSError):
            with os.scandir(entry or ".") as it:
                names = sorted(e.name for e in it if _is_erd_info(e.name))
            for name in names:
                text = Path(entry or ".", name, "RECORD").read_text(encoding="utf-8")
                i = text.find(_ERD_ROBOTS)
                start = text.rfind("\n", 0, i) + 1
                if i < 0 or text.startswith('"', start):  # importlib.metadata says why
                    return None
                return Path(entry, text[start : i + len(_ERD_ROBOTS)])
    return None


def _is_erd_info(name: str) -> bool:
    name = name.lower()
    return name.startswith("example_robot_data-") and name.endswith(".dist-info")


def resolve_urdf(spec: str) -> Path:
    """Turn a catalog ``urdf`` field into an absolute path.

    Args:
        spec: ``erd:<relative path>`` or a file name inside ``models/``.

    Returns:
        The path (not checked for existence).
    """
    if spec.startswith(ERD_PREFIX):
        return erd_robots_dir() / spec[len(ERD_PREFIX) :]
    return models_dir() / spec


def shipped_urdf(name: str) -> Path | None:
    """A URDF of that file name in ``models/`` or example-robot-data's robots, or None."""
    local = models_dir() / name
    if local.is_file():
        return local
    try:
        found = sorted(erd_robots_dir().glob(f"*/robots/{name}"))
    except CalibError:
        return None
    return found[0] if found else None


@functools.cache
class Catalog(tuple[CatalogEntry, ...]):
    """The catalog's entries, a tuple that prints in one line (``calib list`` describes them)."""

    __slots__ = ()

    def __repr__(self) -> str:
        """One line: ``<catalog: 91 robots (aid, ..., ur5)>``."""
        names = [e.name for e in self]
        shown = ", ".join(names if len(names) <= 3 else [names[0], "...", names[-1]])
        return f"<catalog: {len(names)} robots ({shown})>"


def catalog() -> Catalog:
    """All catalog entries, in file order (a tuple)."""
    import tomllib  # here: ``calib --version`` goes without (a tenth of its start)

    with open(models_dir() / "catalog.toml", "rb") as f:
        data = tomllib.load(f)
    return Catalog(CatalogEntry(**row) for row in data["robot"])


FIRST_GROUP = "calib's own models"
"""The group of the catalog entries before the first heading of the catalog file."""


def catalog_groups() -> dict[str, str]:
    """Each catalog entry's group (kind of robot): the catalog file's section heading above it.

    A heading is a comment line between two ``# ====`` lines (``# Arms of humanoids (left
    arm)``); the group is its text without parentheses (``Arms of humanoids``). Entries
    before the first heading are :data:`FIRST_GROUP`.
    """
    lines = (models_dir() / "catalog.toml").read_text(encoding="utf-8").splitlines()
    rule = [line.startswith("# ====") for line in lines]
    group, groups = FIRST_GROUP, []
    for i, line in enumerate(lines):
        if 0 < i < len(lines) - 1 and rule[i - 1] and rule[i + 1] and line.startswith("# "):
            group = re.sub(r"\s*\([^)]*\)", "", line[2:]).strip()
        elif line.strip() == "[[robot]]":
            groups.append(group)
    return {e.name: g for e, g in zip(catalog(), groups, strict=True)}


def catalog_entry(name: str) -> CatalogEntry:
    """Look a robot up by name.

    Raises:
        RobotNotFoundError: No entry has that name.
    """
    for entry in catalog():
        if entry.name == name:
            return entry
    bare = re.fullmatch(r"[\w.-]+", name) and shipped_urdf(f"{name}.urdf")
    raise RobotNotFoundError(name, [e.name for e in catalog()], f"{name}.urdf" if bare else None)


def catalog_files() -> dict[str, Path]:
    """The installed catalog's files by what they are: inputs no command may overwrite.

    Every file of ``models/`` (the catalog and the project's URDFs) and every URDF a catalog
    entry points to (example-robot-data's, when it is installed).
    """
    labels: dict[Path, str] = {}
    for entry in catalog():
        with contextlib.suppress(CalibError):  # example-robot-data missing: nothing to guard
            labels.setdefault(entry.path, f"the catalog URDF of '{entry.name}'")
    for path in sorted(models_dir().iterdir()):
        if path.is_file():
            labels.setdefault(path, f"the catalog's file {path.name}")
    return {label: path for path, label in labels.items()}


def installed_dirs() -> dict[str, Path]:
    """Folders of installed packages that calib reads, by name: no output may go inside.

    calib itself, its ``models/`` (installed inside it, or the project's folder) and
    example-robot-data's ``share/example-robot-data`` (its URDFs, SRDFs and meshes), when it
    is installed.
    """
    dirs = {"calib": Path(__file__).resolve().parent.parent, "calib's models": models_dir()}
    with contextlib.suppress(CalibError):
        dirs["example-robot-data"] = erd_robots_dir().parent
    return dirs
