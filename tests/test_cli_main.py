"""The command line's front door: version, exit codes, no tracebacks."""
from importlib import metadata

import pytest

import nhgait
from nhgait.gaits import cli


def test_version_is_single_sourced(capsys):
    assert nhgait.__version__ == metadata.version("nhgait")
    with pytest.raises(SystemExit) as info:
        cli.main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"nhgait {metadata.version('nhgait')}"


def test_package_has_a_docstring():
    assert "nonholonomic" in nhgait.__doc__


def _boom(exc):
    def run(args):
        raise exc
    return run


def test_bad_input_exits_2_without_traceback(capsys, monkeypatch):
    from nhgait.dynamics.bridge import BridgeError
    parser = cli.build_parser()
    args = parser.parse_args(["derive", "unicycle"])
    monkeypatch.setattr(cli, "build_parser", lambda: _Parser(args, _boom(BridgeError(["cannot convert Foo"]))))
    assert cli.main([]) == 2
    err = capsys.readouterr().err
    assert "cannot convert Foo" in err and "Traceback" not in err


def test_internal_error_exits_3_with_one_line(capsys, monkeypatch):
    args = cli.build_parser().parse_args(["derive", "unicycle"])
    monkeypatch.setattr(cli, "build_parser", lambda: _Parser(args, _boom(ZeroDivisionError("x"))))
    monkeypatch.delenv("NHGAIT_DEBUG", raising=False)
    assert cli.main([]) == 3
    err = capsys.readouterr().err
    assert "internal error (ZeroDivisionError: x)" in err and "Traceback" not in err
    monkeypatch.setenv("NHGAIT_DEBUG", "1")
    with pytest.raises(ZeroDivisionError):
        cli.main([])


class _Parser:
    """A parser stand-in returning fixed arguments whose command raises."""

    def __init__(self, args, func):
        args.func = func
        self.args = args

    def parse_args(self, argv):
        return self.args
