"""Argument types of the command line (gaits/cli/arguments.py): a malformed number is argparse's
usage error (exit status 2, the option named), never an exception inside a command."""
from __future__ import annotations

import argparse

import pytest

from nhgait.gaits.cli.arguments import positive_int, workers


def _parser():
    parser = argparse.ArgumentParser(prog="nhgait plan")
    parser.add_argument("--repeats", type=positive_int, default=1)
    parser.add_argument("--workers", type=workers, default=1)
    return parser


def test_values():
    args = _parser().parse_args(["--repeats", "3", "--workers", "auto"])
    assert (args.repeats, args.workers) == (3, "auto")
    assert _parser().parse_args(["--workers", "2"]).workers == 2


@pytest.mark.parametrize("argv, says", [(["--repeats", "0"], "0 must be at least 1"),
                                        (["--repeats", "2.5"], "'2.5' is not a whole number"),
                                        (["--workers", "many"], "'many' is not a whole number")])
def test_malformed_numbers_are_usage_errors(argv, says, capsys):
    with pytest.raises(SystemExit) as caught:
        _parser().parse_args(argv)
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert says in err and argv[0] in err
