"""One vocabulary on the command line (issue 43): the renamed sweep --task (now --gait, as in
plan and track) still works for one release with a note on stderr; an unknown option of any
subcommand — those added later too — is a usage error (exit 2) with "did you mean …?"."""
from __future__ import annotations

import argparse

import pytest

from nhgait.gaits.cli.main import build_parser

SWEEP = ["sweep", "unicycle", "--grid", "final.x=1", "--out", "out/s"]


def _subparsers(parser):
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def _usage_error(argv, capsys) -> str:
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(argv)
    assert exc.value.code == 2
    return capsys.readouterr().err


def test_sweep_takes_gait_as_plan_and_track_do(capsys):
    args = build_parser().parse_args(SWEEP + ["--gait", "parallel-park"])
    assert args.gait == "parallel-park"
    assert capsys.readouterr().err == ""
    for command in ("plan", "track"):
        assert "--gait" in _subparsers(build_parser())[command]._option_string_actions


def test_the_former_spelling_works_and_says_so(capsys):
    args = build_parser().parse_args(SWEEP + ["--task", "parallel-park"])
    assert args.gait == "parallel-park"
    err = capsys.readouterr().err
    assert "--task is deprecated: it is spelled --gait now" in err and "next release" in err
    assert "--task" not in _subparsers(build_parser())["sweep"].format_help()   # hidden from --help


def test_a_misspelt_former_spelling_suggests_the_new_one(capsys):
    err = _usage_error(SWEEP + ["--taks", "parallel-park"], capsys)
    assert "unknown option --taks: did you mean --gait?" in err


def _commands(parser, prefix=()):
    """(argv prefix, parser) of every (sub)subcommand, e.g. (("bench", "precision"), …)."""
    for name, sub in _subparsers(parser).items():
        if any(isinstance(a, argparse._SubParsersAction) for a in sub._actions):
            yield from _commands(sub, prefix + (name,))
        else:
            yield prefix + (name,), sub


@pytest.mark.parametrize("command, sub", list(_commands(build_parser())), ids=lambda c: " ".join(c)
                         if isinstance(c, tuple) else "")
def test_every_subcommand_suggests_its_options(command, sub, capsys):
    """For each subcommand, each of its long options with one letter dropped is answered with
    that option among the suggestions, even with its required options missing (the mechanism
    is the parser class: no command opts in)."""
    options = sorted(o for a in sub._actions for o in a.option_strings if o.startswith("--")
                     and o != "--help" and len(o) > 5 and a.help is not argparse.SUPPRESS)
    assert options, command
    for option in options:
        typo = option[:3] + option[4:]                    # --gait → --git
        if any(o.startswith(typo) for o in sub._option_string_actions):
            continue                                      # argparse takes an unambiguous prefix
        err = _usage_error([*command, "scene", typo], capsys)
        assert f"unknown option {typo}: did you mean" in err and option in err.split("(options")[0], err
        assert f"nhgait {' '.join(command)}: error" in err


def test_sweep_gait_is_no_longer_unrecognized(capsys):
    """The issue's case: 'sweep --gait' was argparse's bare 'unrecognized arguments'."""
    err = _usage_error(["sweep", "unicycle", "--gaitt", "x", "--grid", "final.x=1", "--out", "o"], capsys)
    assert "unrecognized arguments" not in err and "did you mean --gait" in err
