"""``--measure pixels``: a camera on a link sees a target on a tool (calibrate, simulate, analyze).

``--camera NAME LINK INTRINSICS [X Y Z RX RY RZ]`` names the camera (the ``camera`` column of
OBS.csv and the calibrated URDF's link of its optical frame), the link it is fixed to and its
intrinsics file; the six numbers are its placement on LINK [m, rad; roll-pitch-yaw as URDF].
``--target TARGET.csv`` gives the points in the tool frame ``--tool``. The chain runs from
LINK to the tool; each camera is a pixel term of one problem (:mod:`calib.calibration.pixel_chain`).
"""

from __future__ import annotations

import argparse
import math
import shlex
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from ..core.fileio import json_text
from ..core.words import counted
from ..exceptions import InvalidArgumentError
from .common import (
    check_output_paths,
    given_options,
    print_json,
    robot_words,
    write_calibration,
    write_outputs,
)

if TYPE_CHECKING:
    from ..measurements.pixels import Target

__all__ = [
    "add_pixel_arguments",
    "analyze_pixels_command",
    "calibrate_pixels_command",
    "camera_link",
    "pixel_term_data",
    "refuse_paper",
    "simulate_pixels_command",
]

PIXEL_OPTIONS = ("camera", "target", "noise_px", "refine_targets", "refine_intrinsics")
"""The options of ``--measure pixels`` alone."""

NOT_PIXELS = (
    "folds",
    "marker",
    "world_link",
    "on_robot",
    "fix",
    "free",
    "elastic",
    "loss",
    "noise_mm",
    "points",
    "plot",
    "origins",
    "units",
    "orientation",
    "orientation_columns",
    "orientation_weight",
    "contact",
    "other_foot",
    "pose_weight",
    "shared_planes",
    "known_planes",
    "term",
    "chain",
    "loop",
)
"""``calibrate`` options a pixel calibration does not take (a pixel term beside others is
``--term pixels NAME TOOL OBS.csv``, without ``--measure``; ``plot`` and ``origins``: not
yet for pixels): refused, never ignored."""

NOT_PIXELS_SIMULATE = ("marker", "noise_mm", "noise_mrad", "contacts", "plane", "params")
"""``simulate`` options of the other campaigns, refused with ``--measure pixels`` (its robot
is perturbed in every joint placement, its noise ``--noise-px``)."""

NOT_PIXELS_ANALYZE = ("marker", "markers")
"""``analyze`` options a count of the cameras' unknowns does not use, refused."""


def add_pixel_arguments(
    p: argparse._ActionsContainer, calibrate: bool = False, noise: bool = True
) -> None:
    """``--camera``, ``--target``, and ``--noise-px`` or the refinements.

    ``--noise-px`` (simulate) unless ``noise`` is false (analyze counts, it has no noise);
    ``--refine-targets`` and ``--refine-intrinsics`` instead when ``calibrate``.
    """
    p.add_argument(
        "--camera",
        nargs="+",
        action="append",
        metavar="ARG",
        help="with --measure pixels: NAME LINK INTRINSICS.yaml [X Y Z RX RY RZ], a camera "
        "fixed to LINK (its optical frame: z forward, x right, y down) and its placement on "
        "LINK [m, rad; roll-pitch-yaw as URDF]; once per camera (several: repeat it)",
    )
    p.add_argument(
        "--target", metavar="TARGET.csv", help="with --measure pixels: the points on the tool [m]"
    )
    if calibrate:
        p.add_argument(
            "--refine-targets",
            action="store_true",
            help="with --measure pixels: fit the target points after the first three",
        )
        p.add_argument(
            "--refine-intrinsics",
            action="store_true",
            help="with --measure pixels: fit the camera's intrinsics (focal lengths, principal "
            "point, distortion) with the rest (the report's frames.cameras.NAME.intrinsics)",
        )
    elif noise:
        p.add_argument(
            "--noise-px",
            type=float,
            default=0.0,
            help="with --measure pixels: noise on u and v [px] (default: 0)",
        )


def _refuse(args: argparse.Namespace, dests: tuple[str, ...]) -> None:
    """Refuse the first option of ``dests`` given with ``--measure pixels``."""
    typed = given_options(args, dests)
    if typed:
        raise InvalidArgumentError(f"{typed[0]} is not for --measure pixels")


def refuse_pixel_options(args: argparse.Namespace) -> None:
    """Refuse ``--camera``/``--target`` without ``--measure pixels``."""
    typed = given_options(args, PIXEL_OPTIONS)
    if typed:
        raise InvalidArgumentError(f"{typed[0]} is for --measure pixels")


def refuse_paper(args: argparse.Namespace) -> None:
    """Refuse ``--params paper`` for pixels (``analyze``; ``calibrate`` takes auto, complete).

    Pixels count or fit every joint placement direction they determine, with the target's
    mounting known (the default) or not (``complete``).
    """
    if args.params == "paper":
        raise InvalidArgumentError(
            "pixels determine joint placement directions, not the paper's MDH set: give "
            "--params complete (the target's mounting unknown too) or no --params"
        )


def _cameras(args: argparse.Namespace, several: bool = False) -> tuple:
    """The cameras of ``--camera`` (their placements None where no numbers are given)."""
    cameras = args.camera or []
    if not cameras or (len(cameras) > 1 and not several):
        raise InvalidArgumentError(
            f"--measure pixels takes {'one or more' if several else 'one'} --camera NAME LINK "
            f"INTRINSICS [X Y Z RX RY RZ], got {len(cameras)}"
        )
    out = tuple(_camera(values) for values in cameras)
    names = [c.name for c in out]
    if len(set(names)) != len(names):
        raise InvalidArgumentError("a camera is given twice (--camera NAME ...)")
    return out


def _camera(values: list[str]):
    """One ``--camera NAME LINK INTRINSICS [X Y Z RX RY RZ]``."""
    from ..calibration.pixel_chain import PixelCamera
    from ..kinematics.so3 import rpy_to_matrix
    from ..measurements.intrinsics import read_intrinsics

    if len(values) < 3:
        raise InvalidArgumentError(
            f"--camera takes NAME LINK INTRINSICS [X Y Z RX RY RZ], got {len(values)} values"
        )
    if len(values) not in (3, 9):
        raise InvalidArgumentError(
            f"--camera {values[0]}: its placement is 6 numbers X Y Z RX RY RZ after INTRINSICS "
            f"(or none), got {len(values) - 3}"
        )
    name, link, path = values[:3]
    placement = None
    if len(values) == 9:
        try:
            numbers = [float(v) for v in values[3:]]
        except ValueError:
            numbers = [math.nan]
        if not all(math.isfinite(v) for v in numbers):
            raise InvalidArgumentError(f"--camera {name}: X Y Z RX RY RZ must be numbers")
        import numpy as np

        placement = np.eye(4)
        placement[:3, :3], placement[:3, 3] = rpy_to_matrix(np.array(numbers[3:])), numbers[:3]
    return PixelCamera(name, link, read_intrinsics(path), placement)


def _target(args: argparse.Namespace) -> tuple[Target, tuple[str, ...]]:
    """The target of ``--target`` and its links (its ``link`` column's, or the ``--tool``)."""
    from ..measurements.pixels import read_target

    if args.target is None:
        raise InvalidArgumentError("--measure pixels needs --target TARGET.csv")
    tool = args.tool[-1] if isinstance(args.tool, list) else args.tool
    if isinstance(args.tool, list) and len(args.tool) != 1:
        raise InvalidArgumentError("--measure pixels takes one --tool (the target's link)")
    target = read_target(args.target)
    links = tuple(dict.fromkeys(target.link)) if target.link is not None else (tool,)
    return target, links


def _views(args: argparse.Namespace, cameras, placed: bool = False) -> tuple[tuple, Target]:
    """Each camera with a chain from its link to each of the target's links, and the target.

    ``placed`` (simulate, analyze): a camera given without numbers takes the URDF's placement
    of its link NAME on LINK.
    """
    from ..kinematics.robot import load_chain

    target, links = _target(args)
    if args.base is not None:
        load_chain(args.robot, base=args.base, tool=links[0])  # a frame of the robot
    views = tuple(
        (camera, load_chain(args.robot, base=camera.link, tool=link))
        for camera in cameras
        for link in links
    )
    if placed:
        views = tuple((_placed(camera, chain), chain) for camera, chain in views)
    return views, target


def _placed(camera, chain):
    """``camera`` with its placement: its numbers, else the URDF's link NAME on LINK.

    Raises:
        InvalidArgumentError: No numbers and no URDF link NAME fixed to LINK.
    """
    import dataclasses

    from ..kinematics.placement_export import camera_placement

    if camera.placement is not None:
        return camera
    placement = camera_placement(chain, camera.name, camera.link)
    if placement is None:
        raise InvalidArgumentError(
            f"--camera {camera.name} {camera.link}: the URDF has no link {camera.name} fixed "
            f"to {camera.link}: give the camera's placement on {camera.link} "
            "(X Y Z RX RY RZ after the intrinsics file)"
        )
    return dataclasses.replace(camera, placement=placement)


def _named(args: argparse.Namespace, name: str):
    """The ``--camera`` named ``name``."""
    for camera in _cameras(args, several=True):
        if camera.name == name:
            return camera
    raise InvalidArgumentError(f"--term pixels {name}: give --camera {name} LINK INTRINSICS")


def camera_link(args: argparse.Namespace, name: str) -> str:
    """The link of the ``--camera`` named by ``--term pixels NAME ...`` (its chain's base)."""
    return _named(args, name).link


def pixel_term_data(args: argparse.Namespace, name: str, chain, path: str):
    """``--term pixels NAME TOOL OBS.csv``: the camera's rows of OBS.csv as a pixel term.

    The target (``--target``) is on TOOL: with ``--params complete`` its mounting there is an
    unknown (as ``calibrate --measure pixels --params complete``), else it is exact;
    ``--refine-targets`` and ``--refine-intrinsics`` apply.
    """
    from ..calibration.pixel_chain import PixelData, Unknowns
    from ..measurements.pixels import read_observations

    camera = _named(args, name)
    target = _target(args)[0]
    obs = read_observations(path, chain.joint_names, {camera.name: camera.intrinsics}, target)
    what = Unknowns(args.params == "complete", args.refine_targets, args.refine_intrinsics)
    return PixelData(camera, target, obs, what)


def calibrate_pixels_command(args: argparse.Namespace, recorded) -> int:
    """``calibrate --measure pixels``: one pixel term per camera, one problem (the joint fit).

    ``--params complete`` makes the target's mounting an unknown; either way every joint
    placement direction the pixels determine is fitted (the joint fit's ``complete``).
    """
    from ..calibration.entry import calibrate
    from ..calibration.pixel_chain import PixelData, Unknowns
    from ..calibration.problem import Problem, Term
    from ..measurements.pixels import read_observations

    _refuse(args, NOT_PIXELS)
    if args.data is None:
        raise InvalidArgumentError("--measure pixels needs --data OBS.csv")
    if args.params not in (None, "auto", "complete"):
        raise InvalidArgumentError(
            "--measure pixels fits what the pixels determine (--params auto), or also the "
            f"target's mounting (--params complete), not --params {args.params}"
        )
    views, target = _views(args, _cameras(args, several=True))
    chains = tuple(c for _, c in views)
    outputs = {"--out": args.out, "--report": args.report}
    inputs = {"the URDF": chains[0].urdf_path, "--data": args.data, "--target": args.target}
    inputs |= {f"the intrinsics of --camera {c.name}": c.intrinsics.path for c, _ in views}
    check_output_paths(outputs, {**inputs, "--validate": args.validate})
    lenses = {c.name: c.intrinsics for c, _ in views}
    joints = tuple(dict.fromkeys(j for c in chains for j in c.joint_names))
    obs = read_observations(args.data, joints, lenses, target)
    check = None
    if args.validate:
        check = read_observations(args.validate, joints, lenses, target)
    what = Unknowns(args.params == "complete", args.refine_targets, args.refine_intrinsics)
    links = target.link or (chains[0].tool_frame,) * len(target.point)
    link = dict(zip(target.point, links, strict=True))
    seen = {(c, link[p]) for c, p in zip(obs.camera, obs.point, strict=True)}
    terms = tuple(
        Term(
            c,
            PixelData(cam, target, obs, what),
            None if check is None else PixelData(cam, target, check, what),
        )
        for cam, c in views
        if (cam.name, c.tool_frame) in seen
    )
    problem = Problem(
        terms,
        params="complete",
        max_iterations=args.max_iterations,
        holdout=args.holdout,
        seed=args.seed,
    )
    result = calibrate(problem)
    paths = (Path(args.out), Path(args.report) if args.report else None)
    return write_calibration(
        args,
        result.to_dict(),
        result.summary,
        result.refusal,
        lambda: {paths[0]: result.urdf()},
        paths,
        recorded,
    )


def _postures(chains, configs: int, seed: int, path: str | None = None):
    """Postures of every joint of the chains, random or read.

    Each chain's random draw (the first's wins), or each chain's columns of the
    configurations file ``path`` (``calib design``'s, read once); a random draw warns about
    default joint ranges.
    """
    from ..calibration.pixel_chain import joint_postures
    from ..design.configurations import read_chains_configurations
    from ..measurements.limits import warn_default_ranges

    if path is None:
        for chain in chains:
            warn_default_ranges(chain, "give your own configurations")
    drawn = (
        [c.random_configurations(configs, seed) for c in chains]
        if path is None
        else read_chains_configurations(path, chains)
    )
    return joint_postures(chains, drawn)


def simulate_pixels_command(args: argparse.Namespace) -> int:
    """``simulate --measure pixels``: OBS.csv of the true robot, and the truth (JSON).

    Every ``--camera`` (placed) sees the target at the same postures: one file, the cameras'
    rows one after the other, every joint of their chains in each row.
    """
    import numpy as np

    from ..kinematics.robot import load_chain
    from ..measurements.pixel_simulation import simulate_cameras
    from ..measurements.pixels import observations_csv
    from ..measurements.simulation import robot_of
    from ..measurements.true_robot import true_robot

    _refuse(args, NOT_PIXELS_SIMULATE)
    views, target = _views(args, _cameras(args, several=True), placed=True)
    cameras, chains = tuple(v[0] for v in views), tuple(v[1] for v in views)
    out = Path(args.out)
    truth_path = Path(args.truth) if args.truth else out.with_suffix(".truth.json")
    inputs = {"the URDF": chains[0].urdf_path, "--configs-file": args.configs_file}
    check_output_paths({"--out": out, "--truth": truth_path}, inputs)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "true.urdf"
        robot = robot_of(args.seed, args.robot_seed)
        truth = true_robot(
            list(chains), path, error_mm=args.error_mm, error_mrad=args.error_mrad, seed=robot
        )
        true_chains = [load_chain(str(path), base=c.base_frame, tool=c.tool_frame) for c in chains]
        joints, q = _postures(chains, args.configs, args.seed, args.configs_file)
        lenses = [(c.name, c.placement, c.intrinsics) for c in cameras]
        obs = simulate_cameras(
            true_chains, lenses, target, joints, q, noise_px=args.noise_px, seed=args.seed
        )
    cameras = tuple({c.name: c for c in cameras}.values())
    errors = {name: np.round(E, 15).tolist() for name, E in truth.errors.items()}
    document = {
        "camera": cameras[0].name,
        "link": cameras[0].link,
        "cameras": {c.name: c.link for c in cameras},
        "joint_errors": errors,
    }
    write_outputs({out: observations_csv(obs), truth_path: json_text(document)})
    seen = len(np.unique(obs.q, axis=0))
    names = ", ".join(f"{c.name} on {c.link}" for c in cameras)
    print(
        f"{chains[0].name}: {counted(obs.m, 'pixels')} of "
        f"{counted(len(target.point), 'target points')} in {seen} of "
        f"{counted(len(q), 'postures')}, camera{'s' if len(cameras) > 1 else ''} {names}, noise "
        f"{args.noise_px:g} px -> {out}"
    )
    return 0


def analyze_pixels_command(args: argparse.Namespace) -> int:
    """``analyze --measure pixels``: the unknowns the cameras' pixels determine.

    The library's generic count (:func:`~calib.calibration.pixel_chain.pixel_count`: random
    postures, drawn again until enough see the target).
    """
    from ..calibration.pixel_chain import pixel_count

    _refuse(args, NOT_PIXELS_ANALYZE)
    refuse_paper(args)
    views, target = _views(args, _cameras(args, several=True), placed=True)
    chains = tuple(c for _, c in views)
    joints = tuple(dict.fromkeys(j for c in chains for j in c.joint_names))
    found = pixel_count(
        chains,
        tuple(c for c, _ in views),
        target,
        params=args.params,
        configs=args.configs,
        seed=args.seed,
    )
    cameras = tuple({c.name: c for c, _ in views}.values())
    if args.json:
        print_json(found)
        return 0
    names = ", ".join(f"{c.name} on {c.link}" for c in cameras)
    own = "camera 6" if len(cameras) == 1 else f"cameras {len(cameras)} x 6"
    print(
        f"{chains[0].name}: camera{'s' if len(cameras) > 1 else ''} {names} seeing "
        f"{counted(len(target.point), 'points')} on {chains[0].tool_frame} "
        f"({counted(found['rows'], 'pixels')} in {counted(found['postures'], 'postures')})\n"
        f"unknowns determined: {found['n_base']} of {found['n_unknowns']} ({own}, "
        f"{counted(len(joints), 'joints')} x 6 placement components"
        + (", target mounting 6" if found["mount"] else "")
        + ")"
    )
    for note in found["notes"]:
        print(f"note: {note}")
    print(_next_step(args, found))
    return 0


def _next_step(args: argparse.Namespace, found: dict) -> str:
    """The closing line of ``analyze --measure pixels``: record (or simulate), then calibrate.

    ``calib design`` plans no pixels: the simulation at the postures the count drew (the
    same ``--seed``) shows how many see the target.
    """
    words = [*robot_words(args), "--measure", "pixels"]
    words += [w for camera in args.camera for w in ("--camera", *camera)]
    words += ["--target", args.target]
    simulate = ["simulate", *words, "--configs", str(found["configs"])]
    simulate += ["--seed", str(args.seed)] if args.seed else []
    params = ["--params", "complete"] if args.params == "complete" else []
    calibrate = ["calibrate", *words, *params, "--data", "OBS.csv", "--out", "calibrated.urdf"]
    return (
        f"next: record the pixels at postures where the camera sees the target (calib "
        f"{shlex.join(map(str, [*simulate, '--out', 'obs.csv']))} simulates them: "
        f"{found['postures']} of the {found['configs']} postures see it), then calib "
        f"{shlex.join(map(str, calibrate))}"
    )
