"""The command line's one vocabulary (gaits/cli/vocabulary.py), on a parser built here with a
subcommand: an unknown option is argparse's usage error (status 2) with the close known ones of
*that* subcommand; a former spelling still works, stores where the new one does, says so on
stderr and is suggested by its new name."""
from __future__ import annotations

import pytest

from nhgait.gaits.cli.vocabulary import CommandParser, option_names, renamed


def _parser():
    top = CommandParser(prog="nhgait")
    sub = top.add_subparsers(dest="command")
    sweep = sub.add_parser("sweep")
    sweep.add_argument("--gait")
    sweep.add_argument("--workers", type=int, default=1)
    renamed(sweep, "--task", "--gait")
    return top, sweep


def test_a_former_spelling_works_and_says_so(capsys):
    top, sweep = _parser()
    args = top.parse_args(["sweep", "--task", "walk", "--workers", "2"])
    assert (args.gait, args.workers) == ("walk", 2)
    assert "--task is deprecated: it is spelled --gait now" in capsys.readouterr().err
    assert option_names(sweep) == {"--help": "--help", "--gait": "--gait", "--workers": "--workers",
                                   "--task": "--gait"}


def test_an_unknown_option_gets_the_subcommands_close_names(capsys):
    top, _ = _parser()
    with pytest.raises(SystemExit) as caught:
        top.parse_args(["sweep", "--workrs", "2", "--tsk", "walk"])
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert "unknown option --workrs: did you mean --workers?" in err
    assert "unknown option --tsk: did you mean --gait?" in err           # the new spelling suggested
    assert "(options of nhgait sweep: --gait, --help, --workers)" in err


def test_a_stray_argument_is_a_usage_error(capsys):
    top, _ = _parser()
    with pytest.raises(SystemExit) as caught:
        top.parse_args(["sweep", "--gait", "walk", "extra"])
    assert caught.value.code == 2
    assert "nhgait sweep: error: unexpected argument 'extra'" in capsys.readouterr().err
