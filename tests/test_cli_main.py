"""The command line's front door: version, exit codes, no tracebacks."""
from importlib import metadata

import pytest

import nhgait
from nhgait.gaits.cli import main as cli


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
    from nhgait.dynamics.numerics.bridge import BridgeError
    parser = cli.build_parser()
    args = parser.parse_args(["derive", "unicycle"])
    monkeypatch.setattr(cli, "build_parser",
                        lambda *_: _Parser(args, _boom(BridgeError(["cannot convert Foo"]))))
    assert cli.main([]) == 2
    err = capsys.readouterr().err
    assert "cannot convert Foo" in err
    assert "Traceback" not in err


def test_internal_error_exits_3_with_one_line(capsys, monkeypatch):
    args = cli.build_parser().parse_args(["derive", "unicycle"])
    monkeypatch.setattr(cli, "build_parser", lambda *_: _Parser(args, _boom(ZeroDivisionError("x"))))
    monkeypatch.delenv("NHGAIT_DEBUG", raising=False)
    assert cli.main([]) == 3
    err = capsys.readouterr().err
    assert "internal error (ZeroDivisionError: x)" in err
    assert "Traceback" not in err
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


def test_building_the_parser_imports_no_symbolic_or_integrator_module():
    """`nhgait --help` and the start of every command stay light: sympy and scipy.integrate
    (≈ 0.3 s and 0.5 s to import) are imported by the commands that use them, not by the parser."""
    import subprocess
    import sys
    code = ("import sys; from nhgait.gaits.cli.main import build_parser; build_parser(); "
            "print(sorted(m for m in ('sympy', 'scipy.integrate', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
