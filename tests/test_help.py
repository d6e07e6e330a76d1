"""``--help``: every command's options in named groups, and examples that parse.

Usage errors: one line, one ``calib: error:`` prefix, exit status 2.
"""

from __future__ import annotations

import argparse
import shlex

import pytest

from calib.cli.commands import build_parser, main

UNGROUPED = ("positional arguments", "options")
"""argparse's own sections: every option but ``--help`` belongs to a named group instead."""


def commands() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


COMMANDS = sorted(commands())


def examples(text: str) -> list[str]:
    """The command lines of a help's ``examples:`` section (comments cut, ``\\`` joined)."""
    assert "\nexamples:\n" in text, text
    found: list[str] = []
    going_on = False
    for line in text.split("\nexamples:\n", 1)[1].splitlines():
        command = line.split("  #", 1)[0].strip()
        if going_on:
            found[-1] += " " + command.removesuffix("\\").strip()
        else:
            assert command.startswith("calib "), line
            found.append(command.removesuffix("\\").strip())
        going_on = command.endswith("\\")
    return found


def test_the_commands_are_all_here():
    assert (
        sorted(
            [
                "analyze",
                "calibrate",
                "demo",
                "design",
                "detect",
                "list",
                "predict",
                "show",
                "simulate",
                "sweep",
            ]
        )
        == COMMANDS
    )


@pytest.mark.parametrize("name", COMMANDS)
def test_every_option_is_in_a_named_group(name):
    parser = commands()[name]
    named = [g for g in parser._action_groups if g.title not in UNGROUPED]
    assert named, f"calib {name} --help has no group"
    for group in parser._action_groups:
        if group.title in UNGROUPED:
            loose = [a.dest for a in group._group_actions if a.dest != "help"]
            assert loose == [], f"calib {name}: {loose} outside a named group"
    text = parser.format_help()
    for group in named:
        assert f"\n{group.title}:\n" in text


@pytest.mark.parametrize("name", COMMANDS)
def test_every_help_ends_with_examples_that_parse(name):
    """Each example is a command line the parser accepts (its options exist, its values fit)."""
    text = commands()[name].format_help()
    lines = examples(text)
    assert lines and any(line.startswith(f"calib {name}") for line in lines), lines
    for line in lines:
        argv = shlex.split(line)[1:]
        try:
            build_parser().parse_args(argv)
        except SystemExit as exc:  # pragma: no cover - the failure's message
            pytest.fail(f"{line!r} does not parse (exit {exc.code})")


def test_calib_help_has_examples_that_parse(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for line in examples(out):
        if "COMMAND" not in line:
            build_parser().parse_args(shlex.split(line)[1:])


@pytest.mark.parametrize("name", COMMANDS)
def test_help_exits_0_on_stdout(capsys, name):
    assert main([name, "--help"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"usage: calib {name}") and err == ""


def test_fix_help_says_what_is_held_not_always_fitted(capsys):
    """``--fix``: the frame and markers are fitted, but a gantry's first marker is held."""
    assert main(["calibrate", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "not the frame or markers: fitted, but a gantry's first marker, held at --marker" in out


USAGE_ERRORS = [
    [],  # no command
    ["no-such-command"],
    *([name, "--no-such-flag"] for name in COMMANDS),
    ["analyze", "ur5", "--params", "nothing"],  # a choice
    ["simulate", "ur5", "--out", "x.csv", "--configs", "many"],  # a type
    ["calibrate", "ur5", "--data", "d.csv", "--out", "c.urdf", "--points", "1,1"],
    ["design", "ur5", "--configs", "5", "--configs", "6"],  # given twice
]


@pytest.mark.parametrize("argv", USAGE_ERRORS, ids=[" ".join(a) or "none" for a in USAGE_ERRORS])
def test_a_usage_error_is_one_line_with_one_prefix(tmp_path, monkeypatch, capsys, argv):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1, err
    assert err.startswith("calib: error: ") and err.count("error:") == 1, err
    assert err.rstrip().endswith("--help)"), err
    assert list(tmp_path.iterdir()) == []


UNKNOWN = [["simulate", "ur5", "--out", "-", "--json"], ["show", "ur5", "x"]]


@pytest.mark.parametrize("argv", UNKNOWN)
def test_an_unknown_argument_points_to_the_commands_help(capsys, argv):
    """An option a command does not have said ``(see calib --help)``, whose page lists the
    commands, not that command's options."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == f"calib: error: unrecognized arguments: {argv[-1]} (see calib {argv[0]} --help)\n"


def test_the_parser_factory_is_side_effect_free(capsys):
    """The docs build the CLI reference from build_parser(): nothing printed, same parser."""
    first, second = build_parser().format_help(), build_parser().format_help()
    assert first == second
    assert capsys.readouterr() == ("", "")
