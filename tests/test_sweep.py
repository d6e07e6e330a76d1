"""calib sweep: the whole catalog, no row silently missing, counts equal to `calib analyze`."""

from __future__ import annotations

import csv
import io
import json
import warnings
from pathlib import Path

import pytest
from conftest import COUPLED

from calib import analyze, catalog
from calib.cli.commands import main
from calib.outputs.plots import counts_figure, errors_figure, spectrum_figure
from calib.outputs.sweep import COLUMNS, rows_to_csv, sweep

DATA = Path(__file__).parent / "data"
EXPECTED_ERRORS = {e.name for e in catalog() if e.expect_error}


@pytest.fixture(scope="module")
def pose_rows():
    return sweep(measure="pose", configs=60)


def test_every_catalog_chain_is_a_row_in_order(pose_rows):
    assert [r.robot for r in pose_rows] == [e.name for e in catalog()]
    assert {r.robot for r in pose_rows if r.error} == EXPECTED_ERRORS
    for r in pose_rows:
        if r.error:
            assert r.verdict == "error" and "\n" not in r.error and r.error.strip()


def test_counts_match_theory_on_every_analysable_chain(pose_rows):
    for r in pose_rows:
        if r.error:
            continue
        assert r.tools == len(r.chain.split(" -> ")[1].split(", ")), r
        if r.tools == 1:
            assert r.n_standard == 4 * (r.revolute + r.prismatic + 2) - 2, r
        if r.robot in COUPLED:  # no theory for coupled joints: tests/test_mimic.py
            assert r.n_theory is None and r.n_base_complete == r.n_complete, r
        else:
            theory = 4 * r.revolute + 2 * r.prismatic + 6 * r.tools
            assert r.n_base_complete == r.n_complete == theory, r
        assert r.n_base_paper <= r.n_complete, r
        missing = r.n_complete - r.n_base_paper
        assert r.verdict == ("complete" if missing == 0 else f"misses {missing}"), r


@pytest.mark.parametrize("measure", ["pose", "position"])
def test_sweep_counts_equal_analyze(measure):
    names = ["aid", "stanford", "ur5", "panda", "tiago", "anymal_lf", "human_left_leg", "pr2"]
    rows = sweep(names, measure=measure, configs=80, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for r in rows:
            paper = analyze(r.robot, measure=measure, params="paper", configs=80, seed=3)
            full = analyze(r.robot, measure=measure, params="complete", configs=80, seed=3)
            assert (r.n_base_paper, r.n_base_complete, r.n_complete, r.n_theory) == (
                paper.n_base,
                full.n_base,
                full.n_complete,
                full.n_theory,
            )


def test_extra_urdfs_and_unloadable_ones_are_rows(tmp_path):
    bad = tmp_path / "broken.urdf"
    bad.write_text("<robot name='x'><link name='a'>")
    good = str(DATA / "negative_axes.urdf")
    rows = sweep([], extra=[good, str(bad)], configs=40)
    assert [r.robot for r in rows] == [good, str(bad)]
    assert rows[0].error is None and rows[0].n_base_complete == rows[0].n_complete
    assert rows[1].error and "malformed XML" in rows[1].error


def test_cli_sweep_robots_compares_the_named_ones_alone(capsys):
    """``--robots``: the catalog names a comparison needs (it ran the whole catalog, 91 rows)."""
    good = str(DATA / "negative_axes.urdf")
    code = main(["sweep", "--configs", "40", "--json", "--robots", "panda", "ur5", "--", good])
    assert code == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [r["robot"] for r in rows] == ["panda", "ur5", good]
    assert rows[1]["n_base_complete"] == analyze("ur5", configs=40).n_base


def test_cli_sweep_robots_with_an_unknown_name_is_a_usage_error(tmp_path, capsys):
    """A typo among ``--robots`` stops before any work, as ``calib analyze`` does (it was an
    error row, exit 0); nothing written."""
    csv_out = tmp_path / "rows.csv"
    code = main(["sweep", "--configs", "40", "--robots", "ur5", "ur55", "--csv", str(csv_out)])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "unknown robot 'ur55' (did you mean ur5" in err
    assert not csv_out.exists()


def test_csv_text_has_one_row_per_chain(pose_rows):
    parsed = list(csv.DictReader(io.StringIO(rows_to_csv(pose_rows))))
    assert [p["robot"] for p in parsed] == [r.robot for r in pose_rows]
    assert list(parsed[0]) == list(COLUMNS)


def test_cli_sweep_writes_csv_png_and_json(tmp_path, capsys):
    out_csv, out_png = tmp_path / "s.csv", tmp_path / "s.png"
    code = main(
        [
            "sweep",
            "--measure",
            "position",
            "--configs",
            "40",
            "--params",
            "complete",
            "--csv",
            str(out_csv),
            "--plot",
            str(out_png),
            "--json",
        ]
    )
    assert code == 0
    data = json.loads(capsys.readouterr().out)
    assert data["measure"] == "position" and data["params"] == "complete"
    assert [r["robot"] for r in data["rows"]] == [e.name for e in catalog()]
    assert out_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(list(csv.DictReader(out_csv.open()))) == len(catalog())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.csv", "s.png"]  # no temp files


def test_cli_sweep_of_one_robot_says_what_it_wrote(tmp_path, capsys):
    out_csv = tmp_path / "s.csv"
    assert main(["sweep", "--configs", "30", "--robots", "ur5", "--csv", str(out_csv)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2].startswith("1 chain or tree, 1 analysed, 0 with an error")
    assert lines[-1] == f"wrote {out_csv}" and out_csv.exists()


def test_cli_sweep_plain_output_without_progress_bar(capsys):
    assert main(["sweep", "--configs", "30"]) == 0
    out, err = capsys.readouterr()
    assert "calib sweep" not in err  # no progress bar when stderr is not a terminal
    assert out.count("\n") >= len(catalog()) + 2
    assert f"{len(catalog())} chains" in out


def test_cli_sweep_unwritable_csv_is_one_line_error(tmp_path, capsys):
    code = main(["sweep", "--configs", "20", "--csv", str(tmp_path / "no" / "dir" / "s.csv")])
    err = capsys.readouterr().err
    assert code != 0 and err.count("\n") == 1 and err.startswith("calib: error:")
    assert not (tmp_path / "no").exists()


def test_figures_have_the_expected_content(pose_rows):
    fig = counts_figure(pose_rows)
    shown = [t.get_text() for ax in fig.axes if ax.get_visible() for t in ax.get_xticklabels()]
    assert sorted(shown) == sorted(r.robot for r in pose_rows if r.error is None)
    res = analyze("aid", measure="position", params="paper")
    spec = spectrum_figure(res).axes[0]
    kept, dropped = spec.lines[0].get_ydata(), spec.lines[1].get_ydata()
    assert len(kept) == 23 and len(dropped) == 7
    assert min(kept) > res.tolerance > max(dropped)
    assert errors_figure([1e-3, 2e-3], [1e-6, 2e-6]).axes[0].get_xlabel() == "position error [mm]"


def test_cli_sweep_with_one_bad_output_writes_nothing(tmp_path, capsys):
    out_csv = tmp_path / "s.csv"
    code = main(["sweep", "--configs", "20", "--csv", str(out_csv), "--plot", "/no/such/dir/p.png"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "/no/such/dir" in err
    assert not out_csv.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("argv", "fact"),
    [
        (["sweep", "--configs", "0"], "configurations"),
        (["sweep", "--seed", "-1"], "seed"),
        (["analyze", "ur5", "--seed", "-1"], "seed"),
        (["analyze", "ur5", "--configs", "abc"], "--configs"),
        (["analyze", "ur5", "--marker", "1e308", "0", "0"], "marker"),
        (["show", "ur5", "--tool", ""], "empty"),
    ],
)
def test_cli_rejects_bad_numbers_in_one_line(capsys, argv, fact):
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1 and fact in err, err


def test_counts_figure_is_grouped_by_kind_of_robot_and_readable(pose_rows):
    fig = counts_figure(pose_rows)
    panels = {ax.get_title(): ax for ax in fig.axes if ax.get_visible()}
    kinds = [title.rsplit(" (", 1)[0] for title in panels]
    assert kinds == [
        "calib's own models",
        "Arms",
        "Arms of humanoids",
        "Mobile and legged/aerial manipulators",
        "Chains through coupled joints: fingers of grippers and hands",
        "Legs",
        "Trees: whole robots, several tools sharing joints",
    ]  # the catalog file's section headings, in order
    ok = {r.robot: r for r in pose_rows if r.error is None}
    names = {
        k: [t.get_text() for t in ax.get_xticklabels()]
        for k, ax in zip(kinds, panels.values(), strict=True)
    }
    assert names["calib's own models"] == ["aid", "stanford", "mimic_arm"]
    assert "ur5" in names["Arms"] and "solo12_fl" in names["Legs"]
    assert "talos" in names["Trees: whole robots, several tools sharing joints"]
    for kind, ax in zip(kinds, panels.values(), strict=True):
        paper = [bar.get_height() for bar in ax.patches[: len(names[kind])]]
        assert paper == [ok[n].n_base_paper for n in names[kind]]
    width, height = fig.get_size_inches() * 120  # figure_bytes' dpi
    assert width < 1600 and height < 1600, (width, height)  # was 3,230 pixels wide, one row


def test_cli_sweep_robots_with_a_urdf_file_among_the_names_analyses_it(capsys):
    """A URDF file before ``--`` is analysed as it was (9bd99ee made it 'unknown robot ...:
    give a URDF path', exit 2); a typo still stops (the test above)."""
    good = str(DATA / "negative_axes.urdf")
    code = main(["sweep", "--configs", "40", "--json", "--robots", "ur5", good])
    assert code == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [r["robot"] for r in rows] == ["ur5", good] and rows[1]["error"] is None


def test_counts_figure_of_a_few_robots_keeps_long_panel_titles_inside(capsys):
    # six robots in four kinds make a narrow figure: "Mobile and legged/aerial manipulators
    # (1)" ran past its right edge; the PNG's rightmost pixel columns must be background
    from matplotlib.image import imread

    from calib.outputs.plots import figure_bytes

    rows = sweep(robots=["ur5", "ur10", "panda", "tiago", "talos_left_arm", "stanford"], configs=30)
    pixels = imread(io.BytesIO(figure_bytes(counts_figure(rows))))
    assert pixels.shape[1] < 800  # the narrow case
    assert (pixels[:, -3:, :3] == 1.0).all()  # white: nothing drawn at the right edge


def test_the_survey_page_lists_the_json_rows_fields(capsys):
    """docs/howto/survey.md names every field of `--json`'s object and rows, in order, and
    says that `--json` prints (a file name after it is read as a URDF)."""
    page = (Path(__file__).parents[1] / "docs" / "howto" / "survey.md").read_text()
    assert main(["sweep", "--robots", "twodof", "--configs", "20", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    listed = " ".join(page.split("For a figure of your own", 1)[1].split("\n\n", 1)[0].split())
    top = [f"`{k}`" for k in data]
    assert f"the JSON is one object, {', '.join(top[:-1])} and {top[-1]};" in listed
    fields = [f"`{k}`" for k in data["rows"][0]]
    assert f"{', '.join(fields[:-1])} and {fields[-1]}." in listed.replace(
        " (null where no formula applies)", ""
    )
    assert "`--json` prints" in " ".join(page.split())
