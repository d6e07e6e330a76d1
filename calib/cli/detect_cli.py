"""The ``calib detect`` command: images and their joint readings into OBS.csv and TARGET.csv.

``calib detect IMAGES... --board charuco|checkerboard|aruco --squares COLS ROWS --square S
[--marker M] [--separation G] [--dictionary DICT] --joints JOINTS.csv --camera NAME --out
OBS.csv [--target TARGET.csv] [--intrinsics-out INTRINSICS.yaml]``: the files ``calib
calibrate --measure pixels`` reads (:mod:`calib.measurements.detection_files`). Needs OpenCV
(``pip install calib[vision]``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .common import check_output_paths, command_parser, positive_number, write_outputs

__all__ = ["add_detect_parser", "cmd_detect"]


def _board(args: argparse.Namespace):
    from ..measurements.detection import Board

    return Board(
        args.board,
        args.squares[0],
        args.squares[1],
        square=args.square or 0.0,
        marker=args.marker or 0.0,
        separation=args.separation or 0.0,
        dictionary=args.dictionary,
        legacy=args.legacy_charuco,
    )


def _summary(found, board, intrinsics) -> str:
    """The command's report: what was found where, and the intrinsics' fit."""
    seen = [d for d in found.detections if d.found]
    corners = sum(len(d.point) for d in seen)
    lines = [
        f"{board.kind} board found in {len(seen)} of {len(found.paths)} images "
        f"({found.width}x{found.height} px): {corners} corners"
    ]
    lines += [f"  not found: {path}" for path in found.missed]
    if intrinsics is not None:
        intr, rms = intrinsics
        cam = intr.camera
        lines.append(
            f"intrinsics: fx {cam.fx:.2f} fy {cam.fy:.2f} cx {cam.cx:.2f} cy {cam.cy:.2f} px, "
            f"reprojection RMS {rms:.3f} px"
        )
    return "\n".join(lines)


def cmd_detect(args: argparse.Namespace) -> int:
    """Find the board in each image; write OBS.csv (and TARGET.csv, the intrinsics)."""
    from ..measurements.detection import calibrate_intrinsics, opencv
    from ..measurements.detection_files import detect_images, read_image_joints
    from ..measurements.intrinsics import intrinsics_yaml
    from ..measurements.pixels import observations_csv, target_csv

    board = _board(args)
    images = [Path(p) for p in args.images]
    outputs = {"--out": args.out, "--target": args.target, "--intrinsics-out": args.intrinsics_out}
    inputs = {"--joints": args.joints, **{f"image {p}": p for p in images}}
    check_output_paths(outputs, inputs)
    cv2 = opencv()
    joints = read_image_joints(args.joints)
    found = detect_images(images, board, joints, args.camera)
    files: dict[Path, str | bytes] = {Path(args.out): observations_csv(found.observations)}
    if args.target:
        files[Path(args.target)] = target_csv(board.target(cv2))
    intrinsics = None
    if args.intrinsics_out:
        detections = [d for d in found.detections if d.found]
        source = f"{len(detections)} images of {args.joints}"
        intrinsics = calibrate_intrinsics(detections, board, found.width, found.height, source)
        files[Path(args.intrinsics_out)] = intrinsics_yaml(intrinsics[0])
    write_outputs(files)
    print(_summary(found, board, intrinsics))
    print(f"wrote {', '.join(str(p) for p in files)}")
    return 0


def add_detect_parser(sub) -> None:
    """The ``detect`` subcommand's options."""
    p = command_parser(
        sub,
        "detect",
        "find a board in images: OBS.csv and TARGET.csv for calibrate --measure pixels "
        "(needs OpenCV: pip install calib[vision])",
        [
            "calib detect img/*.png --board charuco --squares 5 7 --square 0.04 --marker 0.03 "
            "--joints joints.csv --camera cam --out obs.csv --target target.csv",
            "calib detect img/*.png --board checkerboard --squares 9 6 --square 0.025 "
            "--joints joints.csv --camera cam --out obs.csv --intrinsics-out cam.yaml",
        ],
    )
    g = p.add_argument_group("images and board")
    g.add_argument("images", nargs="+", metavar="IMAGE", help="the images (any OpenCV reads)")
    g.add_argument(
        "--board", required=True, choices=("charuco", "checkerboard", "aruco"), help="board kind"
    )
    g.add_argument(
        "--squares",
        required=True,
        nargs=2,
        type=int,
        metavar=("COLS", "ROWS"),
        help="squares along the board's x and y (markers, for aruco)",
    )
    g.add_argument("--square", type=positive_number, help="a square's side [m]")
    g.add_argument("--marker", type=positive_number, help="a marker's side [m] (charuco, aruco)")
    g.add_argument(
        "--separation", type=positive_number, help="the gap between two markers [m] (aruco)"
    )
    g.add_argument(
        "--dictionary",
        default="DICT_6X6_250",
        help="OpenCV's ArUco dictionary (default: DICT_6X6_250)",
    )
    g.add_argument(
        "--legacy-charuco",
        action="store_true",
        help="a ChArUco board made by OpenCV before 4.6 (an even number of rows differs)",
    )
    g = p.add_argument_group("robot and camera")
    g.add_argument(
        "--joints",
        required=True,
        metavar="JOINTS.csv",
        help="the joint readings of each image: an 'image' column, then one column per joint",
    )
    g.add_argument("--camera", required=True, metavar="NAME", help="the camera's name")
    g = p.add_argument_group("outputs")
    g.add_argument("--out", required=True, metavar="OBS.csv", help="the observations to write")
    g.add_argument(
        "--target", metavar="TARGET.csv", help="write the board's corners [m, board frame]"
    )
    g.add_argument(
        "--intrinsics-out",
        metavar="INTRINSICS.yaml",
        help="calibrate the camera from the images and write its intrinsics (OpenCV's YAML)",
    )
    p.set_defaults(func=cmd_detect)
