"""Every public function raises a CalibError subclass for bad arguments (issue 11, item 12;
issue 29, item 12: the README's Python section too).

Never AttributeError, TypeError, ValueError or FileNotFoundError from inside calib; the
message is one line. (calibrate, simulate and the measurement files are covered with their
own rewrite, issue 10.)
"""

from __future__ import annotations

import atexit
import dataclasses
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from conftest import chain_of, mdh_of

import calib
from calib import CalibError, Measurement
from calib.calibration import residual_stats
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.entry import calibrate_contacts
from calib.calibration.pixel_chain import PixelCamera, pixel_count
from calib.identification.identifiability import analyze_model
from calib.identification.jacobian import complete_jacobian, identification_jacobian
from calib.identification.parameters import (
    Kind,
    Parameter,
    ParameterSet,
    complete_parameters,
    paper_parameters,
)
from calib.identification.pinhole import Pinhole
from calib.identification.tree_jacobian import (
    tree_complete_jacobian,
    tree_jacobian,
    tree_parameters,
)
from calib.kinematics.catalog import CatalogEntry
from calib.kinematics.mdh import from_lines
from calib.kinematics.tree import load_tree
from calib.kinematics.tree_export import calibrated_tree_urdf, write_calibrated_tree_urdf
from calib.kinematics.urdf_export import calibrated_urdf, measurement_to_base, write_calibrated_urdf
from calib.measurements.intrinsics import Intrinsics
from calib.measurements.pixels import PixelObservations, Target
from calib.measurements.tree_campaign import simulate_tree
from calib.outputs.plots import calibration_figure
from calib.outputs.sweep import marker_count, sweep

CHAIN = chain_of("ur5")
ROOTED = calib.load_chain("ur5", base="world")  # measured from the URDF's root link
MDH = mdh_of("ur5")
PSET = paper_parameters(MDH)
Q = np.zeros((4, 6))
NAN_Q = np.array([[0, 0, np.nan, 0, 0, 0]] * 4)
WRONG_Q = np.zeros((4, 5))
TREE = load_tree("bolt")  # 6 joints, 2 tools
TREE_MODEL = calib.from_tree(TREE)
TREE_SET = tree_parameters(TREE_MODEL)
TREE_Q = np.zeros((4, 6))
ARRAY = np.arange(60.0).reshape(10, 6)  # a notebook's configurations
DATA = calib.simulate(CHAIN, 30, seed=0).measurements
PROBLEM = calib.Problem((calib.Term(CHAIN, DATA),))
TOUCHES = calib.simulate_contacts(CHAIN, 20, seed=0).data
CONFIGS = CHAIN.random_configurations(10, seed=0)
INTRINSICS = Intrinsics(640, 480, Pinhole(600.0, 600.0, 320.0, 240.0))
TARGET = Target(("a", "b", "c"), np.eye(3) * 0.05)
CAMERA = PixelCamera("cam", "base_link", INTRINSICS, np.eye(4))


def _cases():
    """(name, call) for each bad argument: the call must raise a CalibError."""
    other = chain_of("stanford")  # 6 joints, one prismatic
    other_mdh = mdh_of("aid")
    return {
        "load_chain robot=5": lambda: calib.load_chain(5),
        "load_chain robot=None": lambda: calib.load_chain(None),
        "load_chain base=5": lambda: calib.load_chain("ur5", base=5),
        "load_chain tool=[]": lambda: calib.load_chain("ur5", tool=[]),
        "load_chain empty base": lambda: calib.load_chain("ur5", base=" "),
        "load_chain missing file": lambda: calib.load_chain("/no/such/robot.urdf"),
        "load_chain unknown name": lambda: calib.load_chain("nosuchrobot"),
        "load_tree robot=5": lambda: load_tree(5),
        "load_tree tools=str list": lambda: load_tree("talos", tools=["left_sole_link", 5]),
        "load_tree tools=5": lambda: load_tree("talos", tools=5),
        "load_tree file without tools": lambda: load_tree(str(CHAIN.urdf_path)),
        "load_robot tool=[]": lambda: calib.load_robot("ur5", tool=[]),
        "load_robot tool=5": lambda: calib.load_robot("ur5", tool=5),
        "from_tree chain": lambda: calib.from_tree(CHAIN),
        "tree_parameters chain model": lambda: tree_parameters(MDH),
        "tree_parameters label": lambda: tree_parameters(TREE_MODEL, "all"),
        "tree_jacobian shape": lambda: tree_jacobian(TREE_MODEL, TREE_SET, WRONG_Q),
        "tree_jacobian params": lambda: tree_jacobian(TREE_MODEL, "paper", TREE_Q),
        "tree_jacobian foreign set": lambda: tree_jacobian(
            TREE_MODEL, ParameterSet("x", (Parameter(40, Kind.R),)), TREE_Q
        ),
        "tree_jacobian measurement": lambda: tree_jacobian(TREE_MODEL, TREE_SET, TREE_Q, "pose"),
        "tree_jacobian measured": lambda: tree_jacobian(
            TREE_MODEL, TREE_SET, TREE_Q, measured=np.ones((4, 3))
        ),
        "tree_complete_jacobian q": lambda: tree_complete_jacobian(TREE_MODEL, "x"),
        "tree_complete_jacobian model": lambda: tree_complete_jacobian(MDH, Q),
        "from_chain str": lambda: calib.from_chain("ur5"),
        "from_chain tol": lambda: calib.from_chain(CHAIN, parallel_tol=-1),
        "from_lines shapes": lambda: from_lines(np.zeros(3), np.eye(3), [0], np.eye(4)),
        "from_lines names": lambda: from_lines(
            np.zeros((1, 3)), [[0, 0, 1]], [0], np.eye(4), joint_names=("a", "b")
        ),
        "analyze configs='x'": lambda: calib.analyze("ur5", configs="x"),
        "analyze configs=1.5": lambda: calib.analyze("ur5", configs=1.5),
        "analyze seed=-1": lambda: calib.analyze("ur5", seed=-1),
        "analyze measure=5": lambda: calib.analyze("ur5", measure=5),
        "analyze marker": lambda: calib.analyze("ur5", marker="abc"),
        "analyze params": lambda: calib.analyze("ur5", params=["paper"]),
        "analyze base=5": lambda: calib.analyze("ur5", base=5),
        "analyze_model mdh": lambda: analyze_model(CHAIN, "paper", None, Q),
        "analyze_model params": lambda: analyze_model(MDH, 3, None, Q),
        "analyze_model measurement": lambda: analyze_model(MDH, "paper", "pose", Q),
        "analyze_model configs='x'": lambda: analyze_model(MDH, "paper", None, "x"),
        "analyze_model configs shape": lambda: analyze_model(MDH, "paper", None, WRONG_Q),
        "analyze_model configs NaN": lambda: analyze_model(MDH, "paper", None, NAN_Q),
        "analyze_model configs None": lambda: analyze_model(MDH, "paper", None, None),
        "analyze_model ragged": lambda: analyze_model(MDH, "paper", None, [[0], [0, 1]]),
        "analyze_model foreign set": lambda: analyze_model(
            other_mdh.replace(), paper_parameters(mdh_of("panda")), None, np.zeros((4, 6))
        ),
        "identification_jacobian shape": lambda: identification_jacobian(MDH, PSET, WRONG_Q),
        "identification_jacobian NaN": lambda: identification_jacobian(MDH, PSET, NAN_Q),
        "identification_jacobian params": lambda: identification_jacobian(MDH, "paper", Q),
        "complete_jacobian q": lambda: complete_jacobian(MDH, "x"),
        "complete_jacobian measurement": lambda: complete_jacobian(MDH, Q, "pose"),
        "paper_parameters": lambda: paper_parameters(CHAIN),
        "complete_parameters": lambda: complete_parameters(None),
        "ParameterSet.apply shape": lambda: PSET.apply(MDH, np.zeros(3)),
        "ParameterSet.apply NaN": lambda: PSET.apply(MDH, np.full(len(PSET), np.nan)),
        "Measurement.of": lambda: Measurement.of("pose", marker=[1, 2]),
        "Chain.check_configurations": lambda: CHAIN.check_configurations(NAN_Q),
        "Chain.random_configurations": lambda: CHAIN.random_configurations("x", seed=0),
        "Chain.tool_placements": lambda: CHAIN.tool_placements(WRONG_Q),
        "MDHModel.forward": lambda: MDH.forward(WRONG_Q),
        "MDHModel.kinematics": lambda: MDH.kinematics("x"),
        "calibrated_urdf chain": lambda: calibrated_urdf("ur5", MDH, MDH),
        "calibrated_urdf models": lambda: calibrated_urdf(other, MDH, MDH),
        "calibrated_urdf model type": lambda: calibrated_urdf(CHAIN, MDH, None),
        "write_calibrated_urdf missing dir": lambda: write_calibrated_urdf(
            "/no/such/dir/cal.urdf", CHAIN, MDH, MDH
        ),
        "measurement_to_base models": lambda: measurement_to_base(None, MDH),
        "residual_stats result": lambda: residual_stats(None, None),
        "plots.calibration_figure not a result": lambda: calibration_figure("report.json"),
        "calibrate chain": lambda: calib.calibrate("ur5", None),
        "calibrate level=": lambda: calib.calibrate(CHAIN, None, level="paper"),
        "calibrate unknown option": lambda: calib.calibrate(CHAIN, None, levl="paper"),
        "write_calibrated_urdf path": lambda: write_calibrated_urdf(3.5, CHAIN, MDH, MDH),
        "calibrate_tree chain": lambda: calib.calibrate(CHAIN, None),
        "calibrate_contact_chains tree": lambda: calibrate_contact_chains([TREE], [None]),
        "calibrate_contact_chains data": lambda: calibrate_contact_chains([CHAIN], [None]),
        "calibrate_contact_chains empty": lambda: calibrate_contact_chains([], []),
        "entry.calibrate_contacts chain": lambda: calibrate_contacts("ur5", None),
        "entry.calibrate_contacts unknown option": lambda: calibrate_contacts(CHAIN, None, levl=1),
        "calibrate_contact_chains str": lambda: calibrate_contact_chains("ur5", "x"),
        "calibrate_tree level": lambda: calib.calibrate(TREE, None, params="auto"),
        "simulate_tree chain": lambda: simulate_tree(CHAIN),
        "simulate_tree markers": lambda: simulate_tree(TREE, markers=[1, 2]),
        "simulate_tree noise": lambda: simulate_tree(TREE, noise_mm=-1),
        "calibrated_tree_urdf models": lambda: calibrated_tree_urdf(TREE, None, TREE_MODEL),
        "calibrated_tree_urdf tree": lambda: calibrated_tree_urdf(CHAIN, TREE_MODEL, TREE_MODEL),
        "calibrated_urdf tool": lambda: calibrated_urdf(CHAIN, MDH, MDH, tool="x"),
        "calibrated_urdf markers": lambda: calibrated_urdf(CHAIN, MDH, MDH, markers=[1]),
        "calibrated_urdf world": lambda: calibrated_urdf(CHAIN, MDH, MDH, world=("a<b", np.eye(4))),
        "load_calibrated missing": lambda: calib.load_calibrated(CHAIN.urdf_path, "/no/such.json"),
        "load_calibrated not json": lambda: calib.load_calibrated(CHAIN.urdf_path, CHAIN.urdf_path),
        "load_calibrated urdf": lambda: calib.load_calibrated(5, CHAIN.urdf_path),
        "write_calibrated_tree_urdf path": lambda: write_calibrated_tree_urdf(
            3.5, TREE, TREE_MODEL, TREE_MODEL
        ),
        **_third_round_cases(),
    }


def _third_round_cases():
    """Issue 29, item 12: the calls of the README's Python section with wrong arguments (a
    path where data are expected, an empty contact set, a string where an array is)."""
    from calib.design.design import design, evaluate, least_i
    from calib.design.observability import indices
    from calib.measurements.contact_campaign import (
        read_contacts,
        simulate_contacts,
        write_contacts,
    )
    from calib.measurements.contact_loops import read_loop
    from calib.measurements.true_robot import true_robot

    data = calib.simulate(CHAIN, 12, measure="position", seed=0).measurements
    touches = simulate_contacts(CHAIN, 12, "plane", seed=0).data
    folder = Path(tempfile.mkdtemp(prefix="calib-api-errors-"))
    atexit.register(shutil.rmtree, folder, True)
    data_csv, touches_csv = folder / "d.csv", folder / "t.csv"
    calib.write_measurements(data_csv, data)
    write_contacts(touches_csv, touches)
    no_touches = dataclasses.replace(touches, q=np.zeros((0, 6)), ids=(), rows=())
    return {
        "simulate chain=str": lambda: calib.simulate("no_such_robot", 5),
        "simulate configs=str": lambda: calib.simulate(CHAIN, "abc"),
        "simulate seed=-1": lambda: calib.simulate(CHAIN, 5, seed=-1),
        "simulate robot_seed=-1": lambda: calib.simulate(CHAIN, 5, robot_seed=-1),
        "simulate robot_seed=1.5": lambda: calib.simulate(CHAIN, 5, robot_seed=1.5),
        "simulate error_mm=1e300": lambda: calib.simulate(CHAIN, 5, error_mm=1e300),
        "simulate noise_mm=nan": lambda: calib.simulate(CHAIN, 5, noise_mm=np.float64("nan")),
        "read_measurements chain=str": lambda: calib.read_measurements(data_csv, "ur5"),
        "read_measurements path=None": lambda: calib.read_measurements(None, CHAIN),
        "read_measurements path=5": lambda: calib.read_measurements(5, CHAIN),
        "read_measurements columns=str": lambda: calib.read_measurements(data_csv, CHAIN, "pose"),
        "write_measurements data=str": lambda: calib.write_measurements("x.csv", "abc"),
        "write_measurements path=None": lambda: calib.write_measurements(None, data),
        "calibrate data=path": lambda: calib.calibrate(CHAIN, "d.csv"),
        "calibrate validate=path": lambda: calib.calibrate(CHAIN, data, validate="v.csv"),
        "calibrate validate=5": lambda: calib.calibrate(CHAIN, data, validate=5),
        "calibrate validate=touches": lambda: calib.calibrate(CHAIN, data, validate=touches),
        "calibrate max_iterations=3e9": lambda: calib.calibrate(
            CHAIN, data, max_iterations=3_000_000_000
        ),
        "calibrate noise_mm=1e300": lambda: calib.calibrate(CHAIN, data, noise_mm=1e300),
        "calibrate empty contact set": lambda: calib.calibrate(CHAIN, no_touches),
        "calibrate empty validation touches": lambda: calib.calibrate(
            CHAIN, touches, validate=no_touches
        ),
        "calibrate_tree max_iterations=3e9": lambda: calib.calibrate(
            TREE, None, max_iterations=3_000_000_000
        ),
        "simulate_tree error_mm=1e300": lambda: simulate_tree(TREE, 5, error_mm=1e300),
        "simulate_tree robot_seed=-1": lambda: simulate_tree(TREE, 5, robot_seed=-1),
        "simulate_tree seed=-1 configs=array": lambda: simulate_tree(TREE, TREE_Q, seed=-1),
        "calibrate_contact_chains pose_weight=nan": lambda: calibrate_contact_chains(
            [CHAIN], [touches], pose_weight=float("nan")
        ),
        "calibrate_contact_chains empty set": lambda: calibrate_contact_chains(
            [CHAIN], [no_touches]
        ),
        "design chain=str": lambda: calib.design("no_such_robot", 5),
        "design configs=0": lambda: calib.design(CHAIN, 0),
        "design constraints=str": lambda: calib.design(CHAIN, 10, constraints="margin 0.1"),
        "design progress=3": lambda: calib.design(CHAIN, 10, progress=3),
        "read_contacts chain=str": lambda: calib.read_contacts(touches_csv, "ur5", "plane"),
        "read_contacts measure=pose": lambda: calib.read_contacts(touches_csv, CHAIN, "pose"),
        "simulate_contacts configs=str": lambda: calib.simulate_contacts(CHAIN, "abc"),
        "simulate_contacts measure=pose": lambda: calib.simulate_contacts(CHAIN, 5, "pose"),
        "Problem terms=()": lambda: calib.Problem(()),
        "analyze problem and measure": lambda: calib.analyze(
            calib.Problem((calib.Term(CHAIN, data),)), measure="pose"
        ),
        "read_intrinsics missing file": lambda: calib.read_intrinsics("/no/such/intr.yaml"),
        "read_target missing file": lambda: calib.read_target("/no/such/target.csv"),
        "read_observations missing file": lambda: calib.read_observations(
            "/no/such/obs.csv", CHAIN.joint_names, {}
        ),
        "simulate_pixels chain=str": lambda: calib.simulate_pixels(
            "ur5", "cam", np.eye(4), None, None, Q
        ),
        "Term robot=str": lambda: calib.Term("ur5", data),
        "calibrate problem and data": lambda: calib.calibrate(
            calib.Problem((calib.Term(CHAIN, data),)), data
        ),
        "design.design chain=int": lambda: design(5, 5),
        "design.design configs=str": lambda: design(CHAIN, "abc"),
        "design.evaluate chain=str": lambda: evaluate("no_such_robot", Q),
        "design.evaluate q=str": lambda: evaluate(CHAIN, "abc"),
        "design.evaluate no row": lambda: evaluate(CHAIN, np.zeros((0, 6))),
        "design.least_i J=str": lambda: least_i("abc", 3, np.eye(3)),
        "observability.indices model=str": lambda: indices("abc", Q),
        "contact_campaign.read_contacts chain=str": lambda: read_contacts(
            touches_csv, "ur5", "plane"
        ),
        "contact_campaign.read_contacts path=None": lambda: read_contacts(None, CHAIN, "plane"),
        "contact_campaign.simulate_contacts chain=int": lambda: simulate_contacts(5, 30),
        "contact_campaign.simulate_contacts robot_seed=True": lambda: simulate_contacts(
            CHAIN, 3, robot_seed=True
        ),
        "contact_campaign.simulate_contacts contacts>configs": lambda: simulate_contacts(
            CHAIN, 3, contacts=10
        ),
        "contact_campaign.write_contacts data=str": lambda: write_contacts("x.csv", "abc"),
        "contact_loops.read_loop chain=str": lambda: read_loop(touches_csv, "ur5"),
        "contact_loops.read_loop path=None": lambda: read_loop(None, CHAIN),
        "true_robot.true_robot chains=str": lambda: true_robot("ur5", folder / "t.urdf"),
        "true_robot.true_robot path=None": lambda: true_robot([CHAIN], None),
        "true_robot.true_robot measuring=None": lambda: true_robot(
            [CHAIN], folder / "t.urdf", measuring=None
        ),
        "true_robot.true_robot error_mm=nan": lambda: true_robot(
            [CHAIN], folder / "t.urdf", error_mm=float("nan")
        ),
        "true_robot.true_robot seed=-1": lambda: true_robot([CHAIN], folder / "t.urdf", seed=-1),
        "true_robot.true_robot measuring from the root": lambda: true_robot(
            [CHAIN], folder / "t.urdf", measuring=[ROOTED]
        ),
        "true_robot.true_robot over the nominal": lambda: true_robot([CHAIN], CHAIN.urdf_path),
        "calibrate_contact_chains measured from the root": lambda: calibrate_contact_chains(
            [ROOTED], [calib.simulate(ROOTED, 12, measure="position", seed=0).measurements]
        ),
        # An array where a number, a name or a marker goes (a notebook's q, several markers):
        # its repr spanned lines in the message, or a comparison raised ValueError.
        "analyze configs=array": lambda: calib.analyze(CHAIN, configs=ARRAY),
        "analyze marker=(K, 3)": lambda: calib.analyze(CHAIN, marker=ARRAY[:2, :3]),
        "analyze measure=array": lambda: calib.analyze(CHAIN, measure=ARRAY),
        "analyze params=array": lambda: calib.analyze(CHAIN, params=ARRAY),
        "analyze seed=array": lambda: calib.analyze(CHAIN, seed=ARRAY),
        "simulate noise_mm=array": lambda: calib.simulate(CHAIN, 10, noise_mm=ARRAY),
        "simulate params=array": lambda: calib.simulate(CHAIN, 10, params=ARRAY),
        "simulate_contacts contacts=array": lambda: calib.simulate_contacts(
            CHAIN, 10, contacts=ARRAY
        ),
        "design criterion=array": lambda: calib.design(CHAIN, 10, criterion=ARRAY),
        "design params=array": lambda: calib.design(CHAIN, 10, params=ARRAY),
        "design measure=array": lambda: calib.design(CHAIN, 10, measure=ARRAY),
        "design random_sets=array": lambda: calib.design(CHAIN, 10, random_sets=ARRAY),
        "calibrate elastic=array": lambda: calib.calibrate(CHAIN, DATA, elastic=ARRAY),
        "calibrate holdout=array": lambda: calib.calibrate(CHAIN, DATA, holdout=ARRAY),
        "calibrate loss=array": lambda: calib.calibrate(CHAIN, DATA, loss=ARRAY),
        "calibrate max_iterations=array": lambda: calib.calibrate(
            CHAIN, DATA, max_iterations=ARRAY
        ),
        # Touches whose ids are not one per touch: an IndexError inside the fit.
        "calibrate touches with fewer ids": lambda: calib.calibrate(
            CHAIN, dataclasses.replace(TOUCHES, ids=TOUCHES.ids[:3])
        ),
        "calibrate touches with fewer rows": lambda: calib.calibrate(
            CHAIN, dataclasses.replace(TOUCHES, q=TOUCHES.q[:5])
        ),
        # Configurations in degrees: simulated (98.6 rad) where a configurations file is
        # refused, and a calibration of the campaign too.
        "simulate configurations in degrees": lambda: calib.simulate(CHAIN, np.degrees(CONFIGS)),
        "simulate_pixels configurations in degrees": lambda: calib.simulate_pixels(
            CHAIN, "cam", np.eye(4), INTRINSICS, TARGET, np.degrees(CONFIGS)
        ),
        "simulate_tree configurations in degrees": lambda: simulate_tree(
            TREE, np.degrees(TREE.random_configurations(5, seed=0))
        ),
        # An option beside a problem (whose options are in it) was ignored: no rows held out.
        "calibrate problem, holdout=": lambda: calib.calibrate(PROBLEM, holdout=0.25),
        "calibrate problem, fix=": lambda: calib.calibrate(PROBLEM, fix=("d2",)),
        "calibrate problem, seed=": lambda: calib.calibrate(PROBLEM, seed=3),
        "cross_validate folds=1": lambda: calib.cross_validate(CHAIN, DATA, folds=1),
        "cross_validate folds=text": lambda: calib.cross_validate(CHAIN, DATA, folds="5"),
        "cross_validate folds=array": lambda: calib.cross_validate(CHAIN, DATA, folds=ARRAY),
        "cross_validate holdout=": lambda: calib.cross_validate(CHAIN, DATA, holdout=0.2),
        "cross_validate no data": lambda: calib.cross_validate(CHAIN),
        # a problem's options are in it; seed= is the folds' own (shuffled), an integer >= 0
        "cross_validate problem, params=": lambda: calib.cross_validate(PROBLEM, params="frames"),
        "cross_validate problem, seed=-1": lambda: calib.cross_validate(PROBLEM, seed=-1),
        "cross_validate seed=text": lambda: calib.cross_validate(CHAIN, DATA, seed="3"),
        # A loaded robot's frames are its own: another base or tool was ignored (the whole
        # chain analysed where the user asked for a shorter one).
        "analyze tool of a loaded chain": lambda: calib.analyze(CHAIN, tool="wrist_2_link"),
        "load_robot base of a loaded chain": lambda: calib.load_robot(CHAIN, "world"),
        "load_robot tools of a loaded tree": lambda: calib.load_robot(TREE, tool=["FL_FOOT"]),
        # K markers counted (sweep --markers, analyze --markers): a chain, position or pose.
        "sweep.sweep markers=0": lambda: sweep(robots=["ur5"], markers=0),
        "sweep.sweep markers with a contact": lambda: sweep(measure="plane", markers=2),
        "sweep.marker_count chain=str": lambda: marker_count("ur5", 3),
        "sweep.marker_count a tree": lambda: marker_count(TREE, 3),
        "sweep.marker_count markers=text": lambda: marker_count(CHAIN, "3"),
        # the generic pixel count (calib analyze --measure pixels) from Python
        "pixel_chain.pixel_count configs=0": lambda: pixel_count(
            (CHAIN,), (CAMERA,), TARGET, configs=0
        ),
        "pixel_chain.pixel_count seed=-1": lambda: pixel_count(
            (CHAIN,), (CAMERA,), TARGET, seed=-1
        ),
        "pixel_chain.pixel_count q without joints": lambda: pixel_count(
            (CHAIN,), (CAMERA,), TARGET, q=Q
        ),
    }


CASES = _cases()


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_argument_is_a_calib_error(case):
    with pytest.raises(CalibError) as info:
        CASES[case]()
    text = str(info.value)
    assert text.strip() and "\n" not in text, text


def test_every_public_function_is_covered():
    """A new public function must be added to the cases above (or to the rewrite's list)."""
    functions = {
        name
        for name in calib.__all__
        if callable(getattr(calib, name)) and not isinstance(getattr(calib, name), type)
    }
    covered = {case.split()[0] for case in CASES}
    assert functions - {"catalog"} <= covered, functions - covered
    assert all(isinstance(e, CatalogEntry) for e in calib.catalog())


def test_the_python_page_names_every_public_name():
    """docs/reference/python.md said "45 names" and left out ``Columns`` and
    ``cross_validate``: its first paragraph counts ``calib.__all__`` and names each of its
    names but the errors (a CalibError, listed further down the page)."""
    import re

    page = (Path(__file__).resolve().parents[1] / "docs" / "reference" / "python.md").read_text()
    first = page.split("\n\n")[1]
    (count,) = re.findall(r"the public face, (\d+) names", first)
    assert int(count) == len(calib.__all__), (count, len(calib.__all__))
    errors = {n for n in calib.__all__ if isinstance(getattr(calib, n), type)}
    errors = {n for n in errors if issubclass(getattr(calib, n), calib.CalibError)}
    named = set(re.findall(r"`(\w+)`", first))
    missing = sorted(set(calib.__all__) - errors - named)
    assert not missing, missing
    assert errors <= set(re.findall(r"`(?:calib\.)?(\w+)`", page)), errors


def test_every_function_the_docs_document_is_covered():
    """The Python calls outside ``calib.__all__`` that the README and the documentation site
    show (``calib.design.design.evaluate``, ...) are in the cases too, under their module's
    last name."""
    import re

    root = Path(__file__).resolve().parents[1]
    pages = [root / "README.md", *(root / "docs").rglob("*.md")]
    readme = "\n".join(p.read_text() for p in pages if "_build" not in p.parts)
    dotted = set(re.findall(r"calib\.((?:[a-z_]+\.)+[a-z_]+)\(", readme))
    covered = {case.split()[0] for case in CASES}
    wanted = {".".join(name.split(".")[-2:]) for name in dotted if name.count(".") >= 1}
    wanted = {w for w in wanted if not w.startswith(("Measurement.", "calib."))}
    assert wanted <= covered, wanted - covered


def test_simulate_names_the_function_called_and_the_tree_route():
    """``calib.simulate(5)`` named ``from_chain`` (a function the user did not call), and
    ``simulate_contacts`` said "contacts are simulated on must be a Chain"; a tree's name
    is refused as the tree is (evaluate49: a name loads as calib.analyze loads it)."""
    tree = calib.load_robot("bolt")
    cases = {
        (calib.simulate, 5): "simulate takes a Chain (see load_chain), a catalog name or a "
        "URDF path, got int 5",
        (calib.simulate, "bolt"): "got the tree 'bolt': a tree's campaign is "
        "calib.measurements.tree_campaign.simulate_tree",
        (calib.simulate, tree): "got the tree 'bolt': a tree's campaign is "
        "calib.measurements.tree_campaign.simulate_tree",
        (calib.simulate_contacts, 5): "simulate_contacts takes a Chain (see load_chain)",
        (calib.simulate_contacts, tree): "got the tree 'bolt': contacts are simulated on one",
    }
    for (function, robot), said in cases.items():
        with pytest.raises(calib.InvalidArgumentError, match=re.escape(said)):
            function(robot, 10)


def test_simulate_takes_a_robot_name_as_analyze_does():
    """``calib.simulate("ur10", ...)`` is the campaign of ``load_chain("ur10")`` (the catalog's
    base and tool, as ``calib.analyze("ur10")`` loads it; planner49 #8), touches too."""
    named = calib.simulate("ur10", 12, noise_mm=0.05, seed=3)
    loaded = calib.simulate(calib.load_chain("ur10"), 12, noise_mm=0.05, seed=3)
    assert np.array_equal(named.measurements.q, loaded.measurements.q)
    assert np.array_equal(named.measurements.position, loaded.measurements.position)
    assert named.truth.robot == loaded.truth.robot == "ur10"
    touches = calib.simulate_contacts("ur5", 12, "plane", seed=0).data
    assert np.array_equal(touches.q, calib.simulate_contacts(CHAIN, 12, "plane", seed=0).data.q)


def test_results_and_data_print_in_one_line():
    """In a notebook or the REPL, ``calib.analyze(chain)`` printed 87 lines of arrays (a
    dataclass's repr): every result and data set of the API prints one line saying what it is
    (the arrays stay attributes, the text ``summary()``)."""
    campaign = calib.simulate(CHAIN, 12, noise_mm=0.05, seed=1)
    touches = calib.simulate_contacts(CHAIN, 12, "plane", contacts=2, seed=0)
    shown = {
        calib.analyze(CHAIN): "<Identifiability ur5: base_link -> tool0, measure position, "
        "complete set, 25 of 33 identifiable>",
        calib.design(CHAIN, 12, candidates=200): "<Design ur5: 12 configurations of ",
        campaign: "<Campaign ur5: 12 configurations, measure position, noise 0.05 mm, seed 1>",
        campaign.measurements: "<Measurements <simulated ur5>: 12 rows of 6 joints, position, "
        "1 marker>",
        touches: "<ContactCampaign ur5: 12 plane touches of 2 planes, seed 0>",
        campaign.truth: "<SimulationTruth ur5: base_link -> tool0, measure position, 33 "
        "complete parameters perturbed (1 mm, 1 mrad), noise 0.05 mm, seed 1>",
        calib.simulate(CHAIN, 12, "pose", noise_mm=0.05, noise_mrad=0.1).truth: "<Simulation"
        "Truth ur5: base_link -> tool0, measure pose, 33 complete parameters perturbed (1 mm, "
        "1 mrad), noise 0.05 mm, 0.1 mrad, seed 0>",
        touches.truth: "<ContactTruth ur5: 2 planes (table1, table2), 33 complete parameters "
        "perturbed (1 mm, 1 mrad), joint noise 0 mrad, seed 0>",
        touches.data: "<ContactData <simulated ur5>: 12 plane touches of 2 planes, 6 joints>",
        simulate_tree(TREE, 3): "<TreeCampaign <simulated bolt>: 3 configurations x 2 "
        "tools (FL_FOOT, FR_FOOT), ",
        CHAIN: "<Chain ur5: base_link -> tool0, 6 joints>",
        tree_parameters(TREE_MODEL): "<ParameterSet paper: 36 parameters (theta0, ",
        calib.load_robot("ur5", tool=("wrist_2_link", "tool0")): "<Tree ur5: base_link -> "
        "wrist_2_link, tool0, 6 joints>",
        calib.analyze(calib.Problem(calib.Term(CHAIN, campaign.measurements))): "<ProblemAnalysis "
        "ur5: chain, 1 term, ",
    }
    for value, start in shown.items():
        assert repr(value).startswith(start) and "\n" not in repr(value), repr(value)


def test_models_and_the_catalog_print_in_one_line():
    """Failed before: an MDH model printed 5 lines of arrays, a tree's 58, ``calib.catalog()``
    19k characters (every entry's fields): one short line each."""
    shown = {
        calib.from_chain(CHAIN): "<MDHModel base_link -> tool0, 6 joints>",
        TREE_MODEL: "<TreeMDH base_link -> FL_FOOT, FR_FOOT, 6 joints>",
        calib.catalog(): "<catalog: ",
    }
    for value, start in shown.items():
        assert repr(value).startswith(start) and "\n" not in repr(value), repr(value)
        assert len(repr(value)) < 100, repr(value)


def test_a_cameras_data_print_in_one_line():
    """A camera's pieces printed their arrays: PixelData 42,719 characters over hundreds of
    lines for 2088 pixels, the observations, target, camera and intrinsics likewise (a
    pinhole's 8 or more distortion coefficients over lines)."""
    pinhole = Pinhole(600.0, 600.0, 320.0, 240.0, np.linspace(-0.1, 0.1, 8))
    intr = Intrinsics(640, 480, pinhole, "intr.yaml")
    target = Target(("a", "b", "c"), np.eye(3) * 0.05, source="target.csv")
    q = np.zeros((200, 6))
    obs = PixelObservations(
        CHAIN.joint_names, q, ("cam",) * 200, ("a", "b", "c", "a") * 50, np.ones((200, 2))
    )
    camera = calib.PixelCamera("cam", "world", intr, None)
    shown = {
        pinhole: "Pinhole(fx=600.0, fy=600.0, cx=320.0, cy=240.0, distortion=(-0.1, ",
        intr: "<Intrinsics intr.yaml: 640x480 px, fx 600, fy 600, cx 320, cy 240 px>",
        target: "<Target target.csv: 3 points on the tool>",
        obs: "<PixelObservations <observations>: 200 pixels of 3 points, camera cam, 6 joints>",
        camera: "<PixelCamera cam on world, intr.yaml, placed from the URDF or the pixels>",
        calib.PixelData(camera, target, obs): "<PixelData <observations>: 200 pixels of camera "
        "cam>",
    }
    for value, start in shown.items():
        assert repr(value).startswith(start) and "\n" not in repr(value), repr(value)


def test_one_point_number_given_alone_is_asked_as_a_sequence():
    """``Columns(points=1)`` said "points must be integers ..., got 1"."""
    with pytest.raises(calib.InvalidArgumentError, match=r"a sequence of point numbers"):
        calib.Columns(points=1)


def test_a_cameras_placement_given_as_a_list_is_an_array():
    """``PixelCamera(..., placement=np.eye(4).tolist())`` passed the rigid-transform check
    and was kept a list: the fit failed with a TypeError (list indices)."""
    pinhole = Pinhole(600.0, 600.0, 320.0, 240.0)
    camera = calib.PixelCamera(
        "cam",
        "world",
        Intrinsics(640, 480, pinhole),
        [[1.0, 0.0, 0.0, 0.5], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0], [0, 0, 0, 1]],
    )
    assert isinstance(camera.placement, np.ndarray) and camera.placement.dtype == float
    assert camera.placement[0, 3] == 0.5 and not camera.placement.flags.writeable


def test_an_orientation_noise_without_orientation_rows_is_refused():
    """``simulate(chain, m, "position", noise_mrad=0.1)`` drew no orientation noise and said
    nothing (the command line refused it); a pose takes it, and 0 is no noise."""
    with pytest.raises(calib.InvalidArgumentError, match="records no orientation"):
        calib.simulate(CHAIN, 5, "position", noise_mrad=0.1)
    with pytest.raises(calib.InvalidArgumentError, match="records no orientation"):
        calib.simulate(CHAIN, 5, "position", noise_mm=0.1, noise_mrad=0.1)  # noise_mm's: given
    calib.simulate(CHAIN, 5, "position", noise_mrad=0.0)
    calib.simulate(CHAIN, 5, "position", noise_mm=0.1)  # noise_mrad's default: noise_mm's
    rotations = calib.simulate(CHAIN, 5, "pose", noise_mrad=0.1).measurements.rotations
    assert rotations.shape == (5, 3, 3)


def test_a_term_given_to_analyze_points_to_its_problem():
    term = calib.Term(CHAIN, calib.simulate(CHAIN, 12, seed=0).measurements)
    with pytest.raises(calib.InvalidArgumentError, match=re.escape("analyze(Problem((term,)))")):
        calib.analyze(term)
    assert calib.analyze(calib.Problem((term,))).n_base > 0
