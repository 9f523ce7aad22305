"""The subcommand modules of ``nhgait`` called in-process (their ``cmd_*``/``run`` with the
arguments the real parser makes), each against a reference that is not the code:

* ``derive`` prints the Chaplygin sleigh's reduced equations — read back, they are the
  sleigh's closed form (Bloch, *Nonholonomic Mechanics and Control*, §1.7):
  ẋ = v cos θ, ẏ = v sin θ, θ̇ = ω, Ṗ₁ = F + m a ω², Ṗ₂ = τ − m a v ω (P₁ = m v,
  P₂ = (I_c + m a²) ω);
* ``linearize --speed V``: the sleigh's straight motion at speed V has the one non-trivial
  eigenvalue −m a V / (I_c + m a²) (from ω̇ linearised about ω = 0);
* ``analyse``: the sleigh's distribution span{(cos θ, sin θ, 0), ∂θ} grows to the whole
  plane-with-heading at the first bracket: growth vector (2, 3), degree 2;
* ``cache``: a cache folder made here, with files of known sizes, surveyed and cleaned (only
  nhgait's files go);
* ``stopping``: a real SIGTERM to this process inside :func:`stop_signals` unwinds as
  ``Terminated`` with exit status 143 and the handlers are put back;
* ``sweep``, ``track``, ``bench``: the checks done before any work, and the CLI's defaults
  against the API's (one value states them, :class:`TrackingOptions`).
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import threading

import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics.errors import ModelError, Terminated
from nhgait.gaits.cli import analyse, cache, derive, linearize, stopping
from nhgait.gaits.cli import sweep as sweep_cli
from nhgait.gaits.cli import track as track_cli
from nhgait.gaits.cli.main import build_parser
from nhgait.ocp import ProblemError

#: the sleigh's built-in parameter values (dynamics/derivation/scenes), stated as the reference
SLEIGH = {"m": 1.0, "I_c": 0.2, "a": 0.3}


def _run(command, argv) -> tuple:
    """(exit status, stdout) of ``command`` on the arguments ``argv`` parsed by the real parser."""
    args = build_parser().parse_args(argv)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = command(args)
    return status, out.getvalue()


def test_derive_prints_the_sleighs_closed_form():
    status, text = _run(derive.cmd_derive, ["derive", "chaplygin_sleigh"])
    assert status == 0
    names = "x y theta p1 p2 m I_c a F tau"
    x, y, th, p1, p2, m, I_c, a, F, tau = sp.symbols(names, real=True)
    local = dict(zip(names.split(), (x, y, th, p1, p2, m, I_c, a, F, tau), strict=True))
    rates = {line.split("/dt = ")[0].strip()[1:]: sp.sympify(line.split("/dt = ")[1], locals=local)
             for line in text.splitlines() if "/dt = " in line}
    v, omega = p1 / m, p2 / (I_c + m * a ** 2)
    want = {"x": v * sp.cos(th), "y": v * sp.sin(th), "theta": omega,
            "p1": F + m * a * omega ** 2, "p2": tau - m * a * v * omega}
    assert set(rates) == set(want)
    assert all(sp.simplify(rates[k] - want[k]) == 0 for k in want)


def test_linearize_gives_the_sleighs_closed_form_eigenvalue():
    speed = 0.5
    status, text = _run(linearize.cmd_linearize, ["linearize", "chaplygin_sleigh", "--speed", str(speed),
                                                  "--json"])
    assert status == 0
    report = json.loads(text)
    m, I_c, a = SLEIGH["m"], SLEIGH["I_c"], SLEIGH["a"]
    expected = -m * a * speed / (I_c + m * a ** 2)
    eigenvalues = [complex(re, im) for re, im in report["eigenvalues"]]
    assert len(eigenvalues) == 1
    assert eigenvalues[0] == pytest.approx(expected, abs=1e-12)
    assert report["stability"] == "stable"


def test_linearize_reads_its_settings_as_numbers_and_names_every_bad_one():
    from nhgait.dynamics import builtin
    system = builtin("chaplygin_sleigh")
    got = linearize.parse_settings(["q.theta=pi/10", "params.a=0.25", "inputs.F=-1"], system)
    assert got["configuration"] == {"theta": pytest.approx(np.pi / 10, rel=1e-15)}
    assert got["params"] == {"a": 0.25} and got["inputs"] == {"F": -1.0}
    with pytest.raises(ModelError) as bad:
        linearize.parse_settings(["q.thta=1", "speed=2"], system)
    assert "2 problem(s)" in str(bad.value) and "did you mean 'theta'" in str(bad.value)


def test_analyse_gives_the_sleighs_growth_vector():
    status, text = _run(analyse.cmd_analyse, ["analyse", "chaplygin_sleigh", "--json"])
    assert status == 0
    report = json.loads(text)
    assert report["growth_vector"] == [2, 3]
    assert report["degree_of_nonholonomy"] == 2
    (bracket,) = report["brackets"]              # [X₁, X₂] at θ = 0 is the sideways direction
    assert set(bracket["direction"]) == {"y"} and abs(bracket["direction"]["y"]) == pytest.approx(1.0)
    assert report["accessibility"]["rank"] == report["accessibility"]["dimension"] == 5


def test_the_cache_survey_counts_and_clean_removes_only_nhgaits_files(tmp_path):
    folder = tmp_path / "cache"
    (folder / "jit").mkdir(parents=True)
    (folder / ("a" * 64 + ".pkl")).write_bytes(b"x" * 1000)
    (folder / ("b" * 64 + ".pkl")).write_bytes(b"x" * 24)
    (folder / "jit" / "lib.so").write_bytes(b"y" * 300)
    (folder / "jit" / "lib.failed").write_text("{}")
    (folder / "notes.txt").write_text("the user's own file")
    report = cache.survey(folder)
    assert report["entries"]["models"] == {"count": 2, "bytes": 1024}
    assert report["entries"]["libraries"] == {"count": 1, "bytes": 300}
    assert report["entries"]["failed builds"]["count"] == 1
    assert report["bytes"] == 1024 + 300 + 2 and report["pending"] == [] and report["builder"] is None
    assert cache.clean(folder) == 3                    # two models and the jit folder
    assert sorted(p.name for p in folder.iterdir()) == ["notes.txt"]


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread() or os.name != "posix",
                    reason="signal handlers live in the main thread")
def test_a_sigterm_inside_stop_signals_unwinds_as_terminated_and_the_handlers_come_back():
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Terminated), stopping.stop_signals() as stop:
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):                          # the handler runs between bytecodes
            pass
    assert stop.signal == signal.SIGTERM
    assert stop.ending() == (143, "nhgait: terminated")
    assert signal.getsignal(signal.SIGTERM) is before


def test_the_sweep_commands_plot_axes_are_checked_against_the_grid():
    sweep_cli._check_plot("final.y,horizon", ["final.y=0.3:0.5:2", "horizon=3:4:2"])
    with pytest.raises(ProblemError) as bad:
        sweep_cli._check_plot("final.y,T", ["final.y=0.3:0.5:2", "horizon=3:4:2"])
    assert "no grid axis 'T' (axes: final.y, horizon)" in str(bad.value)
    with pytest.raises(ProblemError, match="give two axes X,Y"):
        sweep_cli._check_plot("final.y", ["final.y=0.3:0.5:2"])


def test_the_track_commands_defaults_are_the_apis(tmp_path):
    """``nhgait track`` states no default of its own: samples, seed, noise and the back end
    are TrackingOptions' (and Noise's)."""
    from nhgait.gaits.tracking.request import TrackingOptions
    args = build_parser().parse_args(["track", "unicycle", "--out", str(tmp_path / "t")])
    api = TrackingOptions()
    assert (args.samples, args.seed, args.scheduler, args.workers) == (api.samples, api.seed, api.scheduler,
                                                                       api.workers)
    assert (args.state_noise, args.input_noise) == (api.noise.state, api.noise.input)
    assert args.time_limit == api.plan.time_limit
    bad = build_parser().parse_args(["track", "unicycle", "--samples", "0", "--seed", "-1",
                                     "--out", str(tmp_path / "t")])
    with pytest.raises(ProblemError) as refused:
        track_cli.run(bad)
    assert "--samples must be an integer ≥ 1, got 0" in str(refused.value)
    assert "--seed must be an integer ≥ 0, got -1" in str(refused.value)


def test_bench_precision_refuses_bad_requests_before_any_work(tmp_path):
    from nhgait.gaits.bench import command
    out = tmp_path / "bench"
    args = build_parser().parse_args(["bench", "precision", "unicycle", "--repeats", "0", "--out", str(out)])
    with pytest.raises(ModelError, match="at least 1 timed run per point"):
        command.cmd_bench_precision(args)
    assert not out.exists()
    with pytest.raises(ModelError, match="tolerances must lie in"):
        command._floats("1e-6,2", "--tols")
    with pytest.raises(ModelError, match="unknown formulation"):
        command._formulations("reduced,lagrnge")
