"""What every hostile input and injected fault must get: a clear answer, never a crash.

Shared by the test modules of hostile files (``test_hostile_files.py``), numeric extremes
(``test_numeric_extremes.py``), output locations (``test_output_locations.py``) and cache and
compiler faults (``test_cache_faults.py``). :func:`answer` runs ``nhgait`` in this process
(``main(argv)``, as the console script does) inside a :class:`Sandbox`, and
:meth:`Answer.check` asserts the contract of each case:

* the exit status is one of those expected (0 success, 1 ran but did not succeed, 2 bad input)
  — never 3 (an internal error), never a traceback on stderr;
* the message names the problem (a regular expression the case states);
* nothing is left behind: no temporary file of the cache (``.tmp-*``), of the compiler
  (``.build-*``, ``nhgait-jit-*``, gcc's ``cc*``), of the output checks (``.nhgait-probe-*``)
  or a lock (``.nhgait-lock``) in the sandbox's TMPDIR, cache and output folders, and no child
  process of this one started by the case;
* an answer, not a hang: a watchdog (SIGALRM, :data:`HANG_S`) turns a hang into a failure — a
  guard against minutes, not a timing (there are no timed tests).

Cases that need a real process (signals, kill -9, resource limits) use :func:`run_process`,
which runs the console script (:data:`LAUNCHER`) with an address-space limit (:data:`MEMORY_LIMIT`),
so memory that grows without bound ends the run instead of the machine.
"""
from __future__ import annotations

import contextlib
import io
import os
import re
import resource
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

#: seconds after which a case counts as a hang (a watchdog for minutes-long hangs, not a timing)
HANG_S = 240
#: address-space limit of the processes :func:`run_process` starts (bytes)
MEMORY_LIMIT = 3 << 30
#: names of temporaries nhgait may create and must remove
LEFTOVER = re.compile(r"^(\.tmp-|\.build-|nhgait-jit-|\.nhgait-probe-|\.nhgait-lock$|cc[A-Za-z0-9]{6}\.)")
ROOT = Path(__file__).resolve().parents[1]
#: the console script, with Ctrl-C's handler installed even when this test run was started with
#: SIGINT ignored (a background job): Python installs it only where SIGINT is not ignored
LAUNCHER = ("import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
            "from nhgait.gaits.cli.main import main; sys.exit(main(sys.argv[1:]))")
CAR = str(ROOT / "examples" / "car.toml")


@dataclass
class Sandbox:
    """A private TMPDIR (``tmp``), a folder for outputs (``out``) and the cache folder in use
    (``cache``), checked for leftovers by :meth:`leftovers`."""

    root: Path
    cache: Path
    tmp: Path = field(init=False)
    out: Path = field(init=False)

    def __post_init__(self):
        self.tmp = self.root / "tmpdir"
        self.out = self.root / "out"
        self.tmp.mkdir(parents=True, exist_ok=True)
        self.out.mkdir(parents=True, exist_ok=True)
        self.known = set(self._temporaries())

    def leftovers(self, *extra) -> list:
        """Temporaries (:data:`LEFTOVER`) under the sandbox's folders and ``extra`` ones that
        were not there when the sandbox was made (a shared cache may hold other tests' files)."""
        return sorted(set(self._temporaries(*extra)) - self.known)

    def _temporaries(self, *extra) -> list:
        found = []
        for folder in (self.tmp, self.cache, self.out, *map(Path, extra)):
            if folder.is_dir():
                found += [str(p) for p in folder.rglob("*") if LEFTOVER.match(p.name)]
        return found

    def use_cache(self, monkeypatch, folder: Path) -> Path:
        """Point NHGAIT_CACHE_DIR at ``folder`` (not created) for this test."""
        monkeypatch.setenv("NHGAIT_CACHE_DIR", str(folder))
        self.cache = folder
        return folder


@dataclass(frozen=True)
class Answer:
    """What ``nhgait`` answered: exit ``status``, standard ``out`` and ``err``."""

    status: int
    out: str
    err: str
    new_children: tuple = ()

    def check(self, statuses, said: str | None = None, sandbox: Sandbox | None = None) -> Answer:
        """Assert the contract of the module docstring; ``said`` is a regular expression the
        output (stderr, then stdout) must contain."""
        statuses = (statuses,) if isinstance(statuses, int) else tuple(statuses)
        text = self.err + self.out
        assert "internal error" not in text, text[-3000:]
        assert "Traceback" not in text, text[-3000:]
        assert self.status in statuses, (self.status, text[-3000:])
        if said is not None:
            assert re.search(said, text, re.S), (said, text[-3000:])
        if sandbox is not None:
            assert sandbox.leftovers() == [], sandbox.leftovers()
        assert self.new_children == (), self.new_children
        return self


def answer(argv, *, stdin: str | None = None) -> Answer:
    """``nhgait argv`` run in this process (as the console script), its output captured."""
    from nhgait.gaits.cli.main import main
    out, err = io.StringIO(), io.StringIO()
    before = set(children())
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), watchdog():
        try:
            status = main([str(a) for a in argv])
        except SystemExit as exc:          # argparse: a malformed command line
            status = exc.code if isinstance(exc.code, int) else 2
    return Answer(int(status), out.getvalue(), err.getvalue(), tuple(sorted(set(children()) - before)))


@contextlib.contextmanager
def watchdog(seconds: float = HANG_S):
    """Raise in the main thread after ``seconds`` (a hang becomes a failure, not a stuck run)."""
    def expire(signum, frame):
        raise AssertionError(f"no answer within {seconds:.0f} s: a hang")
    if not hasattr(signal, "SIGALRM"):  # pragma: no cover - Windows
        yield
        return
    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def children() -> list:
    """Live (not zombie) child processes of this process (Linux /proc; [] elsewhere), except
    multiprocessing's resource tracker: one per interpreter, started by the first spawned process
    (a worker pool of an earlier test) and kept until the interpreter ends — not a leftover."""
    me, found = os.getpid(), []
    proc = Path("/proc")
    if not proc.is_dir():  # pragma: no cover
        return found
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            head, tail = (entry / "stat").read_text().rsplit(")", 1)
        except OSError:
            continue
        state, ppid = tail.split()[:2]
        if int(ppid) == me and state not in ("Z", "X") and not _resource_tracker(entry):
            found.append(f"{entry.name} {head.split('(', 1)[1]}")
    return found


def _resource_tracker(entry: Path) -> bool:
    try:
        return b"multiprocessing.resource_tracker" in (entry / "cmdline").read_bytes()
    except OSError:
        return False


def limited(memory: int = MEMORY_LIMIT, file_size: int | None = None):
    """A preexec function: an address-space limit and optionally a file-size limit
    (``ulimit -f``; writes beyond it fail with EFBIG — Python ignores SIGXFSZ)."""
    def setup():  # pragma: no cover - runs in the child
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
        if file_size is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (file_size, file_size))
    return setup


def start_process(argv, sandbox: Sandbox, *, env=None, file_size=None) -> subprocess.Popen:
    """``nhgait argv`` as a new process in its own session, with the sandbox's TMPDIR and
    cache, :data:`MEMORY_LIMIT` and optionally ``file_size`` (its output captured)."""
    environ = {**os.environ, "TMPDIR": str(sandbox.tmp), "NHGAIT_CACHE_DIR": str(sandbox.cache),
               **(env or {})}
    return subprocess.Popen([sys.executable, "-c", LAUNCHER, *map(str, argv)], env=environ,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=limited(file_size=file_size))


def run_process(argv, sandbox: Sandbox, *, env=None, file_size=None, timeout: float = HANG_S) -> Answer:
    """:func:`start_process` and wait for its answer (a hang: killed, and a failure)."""
    proc = start_process(argv, sandbox, env=env, file_size=file_size)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise AssertionError(f"nhgait {' '.join(map(str, argv))}: no answer within {timeout:.0f} s") from None
    return Answer(proc.returncode, out, err)


def make_sandbox(tmp_path: Path, monkeypatch) -> Sandbox:
    """A :class:`Sandbox` in ``tmp_path`` with TMPDIR (and :mod:`tempfile`'s cached choice)
    pointed at its ``tmp`` folder and the session's cache."""
    box = Sandbox(tmp_path, Path(os.environ["NHGAIT_CACHE_DIR"]))
    monkeypatch.setenv("TMPDIR", str(box.tmp))
    monkeypatch.setattr(tempfile, "tempdir", None)
    return box
