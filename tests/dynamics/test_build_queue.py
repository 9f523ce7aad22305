"""One builder per cache, fed by a queue; bounded and stoppable (issue 40).

Checked against the process table (``/proc``), never against mocks: the builders are real
processes started by :func:`~nhgait.dynamics.numerics.background.start_build`, and their compiler
is a fake one (``$NHGAIT_CC``: a shell script that records each run and the key it compiles,
waits while ``<folder>/hold`` exists, then writes its output file) — so these tests need no C
compiler and are fast; the real compile path is exercised by ``test_cold_start.py``. Every wait
polls the process table or the cache with a generous hang-guard; nothing asserts a time.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from nhgait.dynamics.numerics import background, build_queue, builder  # noqa: F401 - the builder imports
from nhgait.dynamics.numerics.background import Builders, start_build
from nhgait.dynamics.numerics.compiler import Toolchain

#: the optimising compiler at -O1
O1 = Toolchain(flags=("-O1",))

pytestmark = pytest.mark.skipif(not Path("/proc/self/cmdline").exists() or os.name != "posix",
                                reason="reads the process table of Linux")
#: the hang-guard of every wait (s): only a broken builder reaches it
GUARD_S = 120.0


class FakeCompiler:
    """``$NHGAIT_CC``: records its pid and the key it compiles (``runs``), holds while ``hold``
    exists, writes its ``-o`` file."""

    def __init__(self, folder: Path):
        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)
        self.script = folder / "fakecc.sh"
        self.script.write_text(
            "#!/bin/sh\n"
            "out=''; prev=''; src=''\n"
            'for a in "$@"; do\n'
            '  if [ "$prev" = "-o" ]; then out="$a"; fi\n'
            '  case "$a" in *.c) src="$a";; esac\n'
            '  prev="$a"\n'
            "done\n"
            f"echo $$ $(basename \"$src\" .c) >> '{folder}/runs'\n"
            f"while [ -e '{folder}/hold' ]; do sleep 0.02; done\n"
            'echo built > "$out"\n')
        self.script.chmod(0o700)

    def hold(self, on: bool) -> None:
        flag = self.folder / "hold"
        flag.touch() if on else flag.unlink(missing_ok=True)

    def runs(self) -> list:
        """[(pid, key)] of every run so far."""
        path = self.folder / "runs"
        return [(int(p), k) for p, k in (line.split() for line in path.read_text().splitlines())] \
            if path.exists() else []


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return "X"


def alive(pid: int) -> bool:
    return _state(pid) not in ("Z", "X")


def builders_of(cache: Path) -> list:
    """The pids of the live builder processes of ``cache`` (their command line names its folders;
    a compiler the builder is forking has its command line until it runs the compiler: not counted)."""
    found = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            cmdline = Path(entry.path, "cmdline").read_bytes()
            ppid = int(Path(entry.path, "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        if b"nhgait.dynamics.numerics.builder" in cmdline and str(cache).encode() in cmdline \
                and alive(int(entry.name)):
            found[int(entry.name)] = ppid
    return sorted(pid for pid, ppid in found.items() if ppid not in found)


def until(condition, what: str, guard: float = GUARD_S):
    """Poll ``condition`` until it is true (its value), failing after the hang-guard."""
    deadline = time.monotonic() + guard
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"not within the hang-guard of {guard:g} s: {what}")
        time.sleep(0.02)


@pytest.fixture
def queue(tmp_path, monkeypatch):
    """A private cache, background builds on, the fake compiler held; every builder of the
    cache ended at the end (the test's own checks come first)."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(cache))
    monkeypatch.setenv("NHGAIT_BACKGROUND_BUILDS", "1")
    fake = FakeCompiler(tmp_path / "cc")
    monkeypatch.setenv("NHGAIT_CC", str(fake.script))
    fake.hold(True)
    yield cache, fake
    fake.hold(False)
    for pid in builders_of(cache):
        os.kill(pid, signal.SIGKILL)


def source(name: str) -> str:
    return f"int {name}(void) {{ return 42; }}\n"


def test_two_builds_asked_for_in_one_cache_give_one_builder(queue):
    cache, fake = queue
    mine = Builders()
    first = start_build(source("a"), O1, salt="t", slot="robot A", builders=mine)
    second = start_build(source("b"), O1, salt="t", slot="robot B", builders=mine)
    assert (first.state, second.state) == ("started", "queued")
    assert first.pid == second.pid
    until(lambda: fake.runs(), "the builder to start its first compile")
    assert builders_of(cache) == [first.pid]
    assert build_queue.holder(cache / "builds").pid == first.pid
    fake.hold(False)
    assert mine.wait(timeout=GUARD_S)
    jit = cache / "jit"
    assert (jit / f"{first.key}.so").exists() and (jit / f"{second.key}.so").exists()
    assert sorted(k for _, k in fake.runs()) == sorted([first.key, second.key])
    until(lambda: not builders_of(cache), "the builder to leave once the queue is empty")
    assert build_queue.holder(cache / "builds") is None
    assert not list((cache / "builds").glob("*.req"))


def test_plans_asking_at_once_from_separate_processes_start_one_builder(queue):
    cache, fake = queue
    script = ("import sys\nfrom nhgait.dynamics.numerics.background import start_build\n"
              "from nhgait.dynamics.numerics.compiler import Toolchain\n"
              "b = start_build(f'int f{sys.argv[1]}(void) {{ return 1; }}\\n', Toolchain(flags=('-O1',)), "
              "salt='t', slot=sys.argv[1])\nprint(b.state, b.pid)\n")
    procs = [subprocess.Popen([sys.executable, "-c", script, str(k)], stdout=subprocess.PIPE, text=True)
             for k in range(4)]
    answers = [p.communicate(timeout=GUARD_S)[0].split() for p in procs]
    states = sorted(a[0] for a in answers)
    assert states == ["queued", "queued", "queued", "started"]
    pids = {int(a[1]) for a in answers}
    assert len(pids) == 1
    assert builders_of(cache) == list(pids)
    fake.hold(False)
    until(lambda: len(list((cache / "jit").glob("*.so"))) == 4, "the four libraries")
    until(lambda: not builders_of(cache), "the builder to leave")
    assert len(fake.runs()) == 4


def test_a_stale_request_is_dropped_and_its_compiler_killed(queue):
    """The newest request per slot (robot and task) wins: one replaced while it compiles has
    its compiler killed, one replaced while it waits is never compiled."""
    cache, fake = queue
    mine = Builders()
    old = start_build(source("old"), O1, salt="t", slot="snakeboard/forward", builders=mine)
    (compiler, key), = until(lambda: fake.runs(), "the first compile")
    assert key == old.key
    waiting = start_build(source("w1"), O1, salt="t", slot="unicycle/park", builders=mine)
    newer_waiting = start_build(source("w2"), O1, salt="t", slot="unicycle/park", builders=mine)
    assert waiting.state == newer_waiting.state == "queued"
    new = start_build(source("new"), O1, salt="t", slot="snakeboard/forward", builders=mine)
    until(lambda: not alive(compiler), "the stale request's compiler to be killed")
    fake.hold(False)
    assert mine.wait(timeout=GUARD_S)
    jit = cache / "jit"
    built = {k for _, k in fake.runs()}
    assert built == {old.key, new.key, newer_waiting.key}
    assert not (jit / f"{old.key}.so").exists()
    assert not (jit / f"{waiting.key}.so").exists()
    assert (jit / f"{new.key}.so").exists() and (jit / f"{newer_waiting.key}.so").exists()
    assert not [p for p in jit.iterdir() if p.name.startswith(".build-")]


@pytest.mark.parametrize("what", ["cache", "jit"])
def test_a_deleted_cache_folder_stops_the_builder_and_its_compiler(queue, what):
    cache, fake = queue
    build = start_build(source("gone"), O1, salt="t", slot="x", builders=Builders())
    (compiler, _), = until(lambda: fake.runs(), "the compile")
    shutil.rmtree(cache if what == "cache" else cache / "jit")
    until(lambda: not alive(build.pid), "the builder to stop")
    until(lambda: not alive(compiler), "its compiler to be killed")
    assert not (cache / "jit" / f"{build.key}.so").exists()


@pytest.mark.parametrize("signame", ["SIGHUP", "SIGTERM"])
def test_a_signal_ends_the_builder_and_its_compiler(queue, signame):
    cache, fake = queue
    build = start_build(source("sig"), O1, salt="t", slot="x", builders=Builders())
    (compiler, _), = until(lambda: fake.runs(), "the compile")
    os.kill(build.pid, getattr(signal, signame))
    until(lambda: not alive(build.pid), "the builder to end")
    until(lambda: not alive(compiler), "its compiler to end")
    assert [p.name for p in (cache / "jit").iterdir()] == []        # no build folder, no library
    assert build_queue.holder(cache / "builds") is None


def test_a_compile_over_its_budget_is_killed_and_not_recorded_as_failed(queue, monkeypatch):
    """No builder outlives its compile budget: the budget (wall seconds) travels with the
    request; at it the compiler is killed, the request dropped, nothing recorded as failed (a
    loaded machine is no reason never to try again) — and the other requests waiting are
    dropped too (a machine too busy for one build is too busy for the next)."""
    cache, fake = queue
    monkeypatch.setattr(background, "budgets", lambda estimate: (0.5, 30.0))
    build = start_build(source("slow"), O1, salt="t", slot="x", builders=Builders())
    start_build(source("next"), O1, salt="t", slot="y", builders=Builders())
    assert build.budget_s == 0.5
    until(lambda: not alive(build.pid), "the builder to give up at its budget")
    assert not any(alive(pid) for pid, _ in fake.runs())
    assert len(fake.runs()) <= 1                          # the next request was dropped with it
    assert [p.name for p in (cache / "jit").iterdir()] == []
    assert not list((cache / "builds").glob("*.req"))


def test_a_stopped_plan_withdraws_its_request_and_stops_an_idle_builder(queue):
    cache, fake = queue
    mine, theirs = Builders(), Builders()
    ours = start_build(source("ours"), O1, salt="t", slot="ours", builders=mine)
    (compiler, _), = until(lambda: fake.runs(), "the compile")
    other = start_build(source("other"), O1, salt="t", slot="other", builders=theirs)
    assert mine.cancel() == 1               # another plan's request waits: the builder goes on
    until(lambda: not alive(compiler), "the withdrawn request's compiler to be killed")
    assert alive(ours.pid)
    until(lambda: len(fake.runs()) == 2, "the other request's compile")
    assert theirs.cancel() == 1             # nothing left: the builder is stopped
    assert not alive(ours.pid)
    assert not builders_of(cache)
    assert not (cache / "jit" / f"{other.key}.so").exists()


def test_without_a_c_compiler_no_builder_is_started(tmp_path, monkeypatch):
    """A PATH without gcc or cc (and no $NHGAIT_CC, $CC): the build is "unavailable", said
    why, and no process is started."""
    from nhgait.dynamics.numerics.compiler import compiler_command
    bare = tmp_path / "bin"
    bare.mkdir()
    for tool in ("sh", "sleep"):
        os.symlink(shutil.which(tool), bare / tool)
    monkeypatch.setenv("PATH", str(bare))
    monkeypatch.delenv("NHGAIT_CC", raising=False)
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("NHGAIT_BACKGROUND_BUILDS", "1")
    assert compiler_command() is None
    build = start_build(source("none"), O1, salt="t", slot="x", builders=Builders())
    assert build.state == "unavailable"
    assert "no C compiler" in build.reason
    assert not builders_of(tmp_path / "cache")


def test_the_queue_is_listed_with_its_builder(queue, capsys):
    """``nhgait cache`` lists the pending builds and the builder (pid, age); ``nhgait cache
    stop`` withdraws them and ends the builder; ``nhgait cache clean`` empties the cache."""
    from nhgait.gaits.cli.main import main
    cache, fake = queue
    build = start_build(source("listed"), O1, salt="t", slot="robot/task", builders=Builders())
    until(lambda: fake.runs(), "the compile")
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    assert str(cache) in out
    assert f"builder pid {build.pid}" in out
    assert "1 pending build" in out and build.key[:12] in out
    assert main(["cache", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert listed["builder"]["pid"] == build.pid
    assert [p["key"] for p in listed["pending"]] == [build.key]
    assert main(["cache", "stop"]) == 0
    assert not alive(build.pid)
    assert not list((cache / "builds").glob("*.req"))
    assert main(["cache", "clean"]) == 0
    assert not cache.exists() or not any(cache.iterdir())


def test_no_background_build_asks_for_none_and_puts_the_setting_back(queue, monkeypatch):
    """``nhgait plan --no-background-build`` (:func:`builds_off`) as $NHGAIT_BACKGROUND_BUILDS=0,
    for that command only."""
    from nhgait.dynamics.numerics.background import builds_off
    from nhgait.gaits.cli.main import build_parser
    cache, _ = queue
    args = build_parser().parse_args(["plan", "unicycle", "--no-background-build", "--out", "x"])
    assert args.no_background_build
    with builds_off(args.no_background_build):
        build = start_build(source("off"), O1, salt="t", slot="x", builders=Builders())
    assert build.state == "off" and "NHGAIT_BACKGROUND_BUILDS" in build.reason
    assert os.environ["NHGAIT_BACKGROUND_BUILDS"] == "1"
    assert not builders_of(cache)
    assert not list((cache / "builds").glob("*.req")) if (cache / "builds").exists() else True
