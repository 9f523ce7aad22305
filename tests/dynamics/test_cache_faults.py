"""A cache fault never costs more than a rebuild, and interrupts leave nothing behind
(contract: tests/adversarial.py). Faults are made as a faulty machine makes them: bits flipped
on disk, files truncated or swapped for a FIFO, a directory that refuses writes (the error a
read-only or full disk raises), a real ``ulimit -f``, a process killed with SIGKILL during a
write or a compile. The compiler is a stand-in script (``$NHGAIT_CC``) that writes a temporary
into ``$TMPDIR`` as gcc does (``cc*.s``), so these tests need no C compiler. References: the
bytes on disk, an uncached derivation, the process table."""
from __future__ import annotations

import errno
import os
import random
import signal
import stat
import subprocess
import sys
import textwrap
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from adversarial import children, run_process, start_process

from nhgait.dynamics.numerics import cache

posix_only = pytest.mark.skipif(os.name != "posix", reason="POSIX processes and files")


@pytest.fixture
def private_cache(sandbox, monkeypatch):
    """An empty cache directory of this test (NHGAIT_CACHE_DIR)."""
    return sandbox.use_cache(monkeypatch, sandbox.root / "cache")


def _entry(private_cache):
    """(key, path, bytes) of the unicycle's reduced model written into the private cache."""
    from nhgait.dynamics import derive, unicycle
    model = derive(unicycle(), "reduced")
    path = cache.path_for(model.provenance.key)
    return model.provenance.key, path, path.read_bytes()


def _rhs(model):
    z = np.linspace(-0.7, 0.9, len(model.state_names))
    u = np.array([0.3, -0.2])
    return np.ravel(model.numeric.call("rhs", 0.4, z, u, model.numeric.params()))


# ----------------------------------------------------------------------------- damaged entries
FLIPS = 24


def test_a_flipped_bit_anywhere_is_refused_before_anything_is_unpickled(private_cache, monkeypatch):
    """24 seeded single-bit flips (format line, header, payload): each entry is refused with a
    warning naming why, and pickle never sees its bytes (a damaged pickle of CasADi objects
    crashed the interpreter with SIGSEGV, or hung it, in 2 of 48 flips)."""
    from nhgait.dynamics.derivation.formulations import _Entry  # noqa: PLC2701 - the cached type
    key, path, good = _entry(private_cache)
    unpickled = []
    loads = cache.pickle.loads
    monkeypatch.setattr(cache.pickle, "loads", lambda data: unpickled.append(len(data)) or loads(data))
    rng = random.Random(29)
    header_end = good.index(b"\n", len(b"NHGAIT-CACHE-ENTRY 2\n")) + 1
    positions = [rng.randrange(header_end) for _ in range(6)] + [rng.randrange(header_end, len(good))
                                                                 for _ in range(FLIPS - 6)]
    for position in positions:
        damaged = bytearray(good)
        damaged[position] ^= 1 << rng.randrange(8)
        path.write_bytes(bytes(damaged))
        with pytest.warns(cache.UntrustedCacheWarning, match="ignoring unreadable cache entry"):
            assert cache.load(key, _Entry) is None
    assert unpickled == []
    path.write_bytes(good)
    assert isinstance(cache.load(key, _Entry), _Entry)
    assert len(unpickled) == 1


DAMAGE = [
    ("truncated to half", lambda good: good[: len(good) // 2], r"truncated|damaged"),
    ("one byte appended", lambda good: good + b"\0", r"truncated or extended"),
    ("an old format", lambda good: b"\x80\x05" + good, r"not an nhgait cache entry"),
    ("empty", lambda good: b"", r"not an nhgait cache entry"),
    ("a header without its payload", lambda good: good[: good.index(b"\n", 30) + 1], r"truncated|damaged"),
    ("a header of a huge size", lambda good: good.replace(b'"size": ', b'"size": 99999999', 1),
     r"damaged|truncated"),
]


@pytest.mark.parametrize("damage, said", [pytest.param(*c[1:], id=c[0]) for c in DAMAGE])
def test_a_damaged_entry_costs_one_rebuild(damage, said, private_cache):
    """The model is derived again (no cache hit), equals an uncached derivation, is written
    again, and the next derive is a hit."""
    from nhgait.dynamics import derive, unicycle
    key, path, good = _entry(private_cache)
    path.write_bytes(damage(good))
    with pytest.warns(cache.UntrustedCacheWarning, match=said):
        rebuilt = derive(unicycle(), "reduced")
    assert not rebuilt.provenance.cache_hit
    np.testing.assert_allclose(_rhs(rebuilt),
                               _rhs(derive(unicycle(), "reduced", use_cache=False)), rtol=1e-14)
    assert derive(unicycle(), "reduced").provenance.cache_hit


def _swap(kind):
    def make(path, key):
        path.unlink()
        if kind == "fifo":
            os.mkfifo(path, 0o600)
        elif kind == "directory":
            path.mkdir(0o700)
        elif kind == "link":
            path.symlink_to("/dev/zero")
        elif kind == "other key":
            cache.store(cache.make_key("another"), {"x": 1})
            os.replace(cache.path_for(cache.make_key("another")), path)
    return make


SWAPS = [("a FIFO (would block the reader)", "fifo", r"is not a regular file"),
         ("a directory", "directory", r"is not a regular file"),
         ("a link to /dev/zero", "link", r"is a symbolic link"),
         ("another key's entry", "other key", r"written for another key")]


@posix_only
@pytest.mark.parametrize("kind, said", [pytest.param(*c[1:], id=c[0]) for c in SWAPS])
def test_an_entry_swapped_for_something_else_is_refused(kind, said, private_cache):
    from nhgait.dynamics.derivation.formulations import _Entry  # noqa: PLC2701
    key, path, _ = _entry(private_cache)
    _swap(kind)(path, key)
    with pytest.warns(cache.UntrustedCacheWarning, match=said):
        assert cache.load(key, _Entry) is None


# ----------------------------------------------------------------------------- unwritable caches
WRITE_FAULTS = [("read-only file system", "mkstemp", errno.EROFS), ("no space left", "replace", errno.ENOSPC),
                ("quota exhausted", "replace", errno.EDQUOT), ("file too large", "replace", errno.EFBIG),
                ("permission denied", "mkstemp", errno.EACCES)]


@pytest.mark.parametrize("where, code", [pytest.param(*c[1:], id=c[0]) for c in WRITE_FAULTS])
def test_a_cache_that_cannot_be_written_warns_once_and_the_run_goes_on(where, code, private_cache,
                                                                       monkeypatch):
    """Two derivations into a cache that refuses every write: both succeed uncached, the
    warning is shown once (Python's default filter: one text, one place), no temporary is left."""
    from nhgait.dynamics import derive, unicycle

    def fail(*args, **kwargs):
        raise OSError(code, os.strerror(code))
    cache.trusted_dir()                                    # the directory exists; its writes fail
    monkeypatch.setattr(cache.tempfile if where == "mkstemp" else cache.os, where, fail)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("default")
        first = derive(unicycle(), "lagrange")
        second = derive(unicycle(), "hamilton")
    said = [str(w.message) for w in seen if issubclass(w.category, cache.UntrustedCacheWarning)]
    assert len(said) == 1
    assert os.strerror(code) in said[0]
    assert "results are not cached" in said[0]
    assert not first.provenance.cache_hit
    assert not second.provenance.cache_hit
    assert list(private_cache.iterdir()) == []


@posix_only
def test_a_real_file_size_limit_leaves_a_working_run(sandbox, private_cache):
    """``ulimit -f`` 30 kB in a real process: the model entries (42 and 58 kB) and the compiled
    library (44 kB) cannot be written; the run warns once and finishes (exit 0) with the final
    state of an unlimited run, and leaves no temporary."""
    args = ["simulate", "unicycle", "--method", "compiled", "--out"]
    limited = run_process([*args, sandbox.out / "t.csv"], sandbox, file_size=30_000)
    limited.check(0, r"nhgait: warning: cannot write the cache directory .* \(File too large\)", sandbox)
    assert limited.err.count("cannot write the cache directory") == 1
    assert [p.name for p in private_cache.iterdir() if p.suffix == ".pkl"] == []
    run_process([*args, sandbox.out / "u.csv"], sandbox).check(0, None, sandbox)
    last = [float(v) for v in (sandbox.out / "t.csv").read_text().splitlines()[-1].split(",")]
    again = [float(v) for v in (sandbox.out / "u.csv").read_text().splitlines()[-1].split(",")]
    np.testing.assert_allclose(last, again, rtol=1e-6, atol=1e-9)


@posix_only
@pytest.mark.parametrize("setting", ["a world-writable folder", "a file", "/dev/null"])
def test_a_refused_cache_location_is_not_used_for_anything(setting, sandbox):
    """The cache directory refused (0777), a file or a device (a fresh process, so nothing is
    remembered from this one): a warning, the run succeeds, and nothing is created there — no
    jit/ folder, no library (compiled in a private folder of TMPDIR and removed)."""
    if setting == "a world-writable folder":
        folder = sandbox.root / "cache"
        folder.mkdir()
        os.chmod(folder, 0o777)
    elif setting == "a file":
        folder = sandbox.root / "cache"
        folder.write_text("x")
    else:
        folder = Path("/dev/null")
    sandbox.cache = folder
    got = run_process(["simulate", "unicycle", "--method", "compiled", "--out",
                       sandbox.out / "t.csv"], sandbox)
    got.check(0, r"nhgait: warning: (refusing the cache directory|cannot (create|write) the cache directory)")
    if folder.is_dir():
        assert list(folder.iterdir()) == []
    assert list(sandbox.tmp.iterdir()) == []


# ----------------------------------------------------------------------------- temporaries
def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@posix_only
def test_temporaries_of_dead_writers_go_with_the_next_write(private_cache):
    """A writer killed during a write leaves ``.tmp-<host>-<pid>-…``: the next write removes
    those whose process is gone (this host) and those older than STALE_TMP_S, and keeps a live
    writer's and a young one of another host."""
    folder = cache.trusted_dir()
    host = cache.temporary_prefix().split("-")[1]
    dead, live = _dead_pid(), os.getppid()
    names = {"dead": f".tmp-{host}-{dead}-abc.pkl", "live": f".tmp-{host}-{live}-abc.pkl",
             "other host": f".tmp-deadbeef-{dead}-abc.pkl", "old": ".tmp-abc.pkl", "young": ".tmp-xyz.pkl"}
    for name in names.values():
        (folder / name).write_bytes(b"half an entry")
    old = time.time() - cache.STALE_TMP_S - 60
    os.utime(folder / names["old"], (old, old))
    cache.store(cache.make_key("next write"), {"answer": 42})
    left = sorted(p.name for p in folder.iterdir() if p.name.startswith(".tmp-"))
    assert left == sorted([names["live"], names["other host"], names["young"]])


FAKE_CC = textwrap.dedent("""\
    #!/bin/sh
    # a stand-in C compiler: a temporary in $TMPDIR as gcc's cc*.s, then the library (or a wait)
    out=""; prev=""
    for a in "$@"; do [ "$prev" = "-o" ] && out="$a"; prev="$a"; done
    echo "assembler" > "$TMPDIR/ccFAKE01.s"
    echo "$$" >> "{folder}/started"
    if [ -e "{folder}/slow" ]; then exec sleep 60; fi
    echo "library" > "$out"
""")


@pytest.fixture
def fake_cc(sandbox, monkeypatch):
    """The stand-in compiler as $NHGAIT_CC; ``fake_cc / "slow"`` makes it wait."""
    folder = sandbox.root / "cc"
    folder.mkdir()
    script = folder / "cc.sh"
    script.write_text(FAKE_CC.format(folder=folder))
    script.chmod(0o755)
    monkeypatch.setenv("NHGAIT_CC", str(script))
    return folder


@posix_only
def test_the_compilers_temporaries_stay_in_nhgaits_build_folder(fake_cc, sandbox, private_cache):
    """gcc writes cc*.s into $TMPDIR: the compiler runs with TMPDIR in the build folder, so the
    user's TMPDIR stays empty and the build folder is gone after the build."""
    from nhgait.dynamics.numerics.compiler import build_library, jit_dir
    lib = build_library("int nhgait_answer(void) { return 42; }")
    assert lib.path.read_text() == "library\n"
    assert not lib.private
    assert list(sandbox.tmp.iterdir()) == []
    assert sorted(p.suffix for p in jit_dir().iterdir()) == [".json", ".so"]


@posix_only
def test_an_interrupted_compile_leaves_nothing(fake_cc, sandbox, private_cache):
    """Ctrl-C while the compiler waits: KeyboardInterrupt, the compiler killed, no build folder,
    no temporary in TMPDIR, no child process. A real SIGINT to the main thread (as a terminal
    sends it), which the compiler's start holds back until the compiler is registered —
    ``_thread.interrupt_main`` ignores the signal mask and could land inside ``Popen``."""
    import signal

    from nhgait.dynamics.numerics.compiler import build_library, jit_dir
    (fake_cc / "slow").touch()
    started = fake_cc / "started"
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)   # xdist workers ignore it
    main = threading.main_thread().ident

    def interrupt_when_started():
        deadline = time.monotonic() + 120                    # a hang guard
        while time.monotonic() < deadline and not started.exists():
            time.sleep(0.01)
        signal.pthread_kill(main, signal.SIGINT)
    threading.Thread(target=interrupt_when_started, daemon=True).start()
    try:
        with pytest.raises(KeyboardInterrupt):
            build_library("int f(void) { return 1; }", timeout=120)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert list(jit_dir().iterdir()) == []
    assert list(sandbox.tmp.iterdir()) == []
    assert children() == []




def _wait_for(path: Path, seconds: float = 120) -> None:
    deadline = time.monotonic() + seconds
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.02)


def _gone(pid: int) -> bool:
    """No such process, or only its zombie (its parent died; reaping is init's business)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True
    return state in ("Z", "X")


@posix_only
@pytest.mark.parametrize("signame, status", [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_signal_during_the_compile_leaves_nothing(signame, status, fake_cc, sandbox, private_cache):
    """``nhgait simulate --method compiled`` signalled while its compiler runs: exit 130/143,
    the compiler gone, nothing in TMPDIR (gcc's cc*.s were left there 8 times out of 8), no
    build folder."""
    (fake_cc / "slow").touch()
    proc = start_process(["simulate", "unicycle", "--method", "compiled", "--out", sandbox.out / "t.csv"],
                         sandbox, env={"NHGAIT_CC": os.environ["NHGAIT_CC"]})
    try:
        _wait_for(fake_cc / "started")
        os.kill(proc.pid, getattr(signal, signame))
        out, err = proc.communicate(timeout=120)          # a hang guard
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == status, err[-2000:]
    compiler = int((fake_cc / "started").read_text().split()[0])
    deadline = time.monotonic() + 120                     # polled until gone; fails only on a hang
    while not _gone(compiler):
        assert time.monotonic() < deadline, f"the compiler {compiler} outlived its run"
        time.sleep(0.02)
    assert list(sandbox.tmp.iterdir()) == []
    assert sandbox.leftovers() == []


@posix_only
def test_kill_9_during_the_compile_is_cleaned_by_the_next_build(fake_cc, sandbox, private_cache):
    """SIGKILL of nhgait while its compiler runs: the compiler dies with it (PR_SET_PDEATHSIG on
    Linux); the build folder it leaves (named for its host and pid) goes with the next build,
    at once, not an hour later."""
    from nhgait.dynamics.numerics.compiler import build_library, jit_dir
    (fake_cc / "slow").touch()
    proc = start_process(["simulate", "unicycle", "--method", "compiled", "--out", sandbox.out / "t.csv"],
                         sandbox, env={"NHGAIT_CC": os.environ["NHGAIT_CC"]})
    try:
        _wait_for(fake_cc / "started")
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate()
    left = [p.name for p in jit_dir().iterdir()]
    assert len(left) == 1
    assert left[0].startswith(f".build-{cache.temporary_prefix().split('-')[1]}-{proc.pid}-")
    (fake_cc / "slow").unlink()
    build_library("int g(void) { return 2; }")
    assert sorted(p.suffix for p in jit_dir().iterdir()) == [".json", ".so"]
    assert sandbox.leftovers() == []


KILLED_WRITER = textwrap.dedent("""
    import os, signal
    from nhgait.dynamics.numerics import cache
    cache.os.replace = lambda *args: os.kill(os.getpid(), signal.SIGKILL)   # killed before the rename
    cache.store(cache.make_key("killed"), {"answer": 42})
""")


@posix_only
def test_kill_9_during_a_cache_write_is_cleaned_by_the_next_write(sandbox, private_cache):
    """The writer dies between its write and its rename: its .tmp-* is never read, and the
    next write (of any entry) removes it."""
    env = {**os.environ, "NHGAIT_CACHE_DIR": str(private_cache)}
    proc = subprocess.run([sys.executable, "-c", KILLED_WRITER], env=env, capture_output=True, timeout=120)
    assert proc.returncode == -signal.SIGKILL
    (left,) = [p.name for p in private_cache.iterdir()]
    assert left.startswith(".tmp-")
    assert left.endswith(".pkl")
    assert cache.load(cache.make_key("killed"), dict) is None
    cache.store(cache.make_key("another"), {"answer": 1})
    assert [p.name for p in private_cache.iterdir()] == [cache.path_for(cache.make_key("another")).name]


@posix_only
def test_a_private_folder_of_a_dead_process_goes_with_the_next_private_build(fake_cc, sandbox, monkeypatch):
    """With the cache refused, libraries are built in ``nhgait-jit-<host>-<pid>-…`` of TMPDIR; a
    folder of a process that died there is removed by the next private build."""
    from nhgait.dynamics.numerics.compiler import build_library
    folder = sandbox.root / "cache"
    folder.mkdir()
    os.chmod(folder, 0o777)
    sandbox.use_cache(monkeypatch, folder)
    stale = sandbox.tmp / f"nhgait-jit-{cache.temporary_prefix().split('-')[1]}-{_dead_pid()}-x"
    stale.mkdir()
    (stale / "half.so").write_text("x")
    with pytest.warns(cache.UntrustedCacheWarning, match="writable by group or others"):
        lib = build_library("int h(void) { return 3; }")
    assert lib.private
    assert not stale.exists()
    assert stat.S_ISREG(lib.path.stat().st_mode)
    import shutil
    shutil.rmtree(lib.path.parent)
    assert list(sandbox.tmp.iterdir()) == []
    assert list(folder.iterdir()) == []
