"""Output locations are checked before the work, one run writes a directory at a time, and a write
that fails at the end loses nothing (contract: tests/adversarial.py). The order is shown with a
scene that does not exist: a bad location is reported instead of the missing scene, so it was
checked first; faults of the file system are injected where nhgait meets it (``mkstemp``,
``fsync``, the figure and CSV writers, the store), as a full or read-only disk raises them."""
from __future__ import annotations

import errno
import json
import os
import re
import signal
import subprocess
import sys
import textwrap

import pytest
from adversarial import answer, run_process

NOWHERE = "no_such_scene.toml"          # reported only if the location passed its checks
PLAN = ["plan", "unicycle", "--gait", "parallel-park", "--intervals", "20", "--no-jit", "--quiet"]
SWEEP = ["sweep", "unicycle", "--gait", "parallel-park", "--set", "intervals=20", "--workers", "0",
         "--no-plots", "--quiet"]


def _file(box):
    path = box.root / "a_file"
    path.write_text("x")
    return path


def _fifo(box):
    path = box.root / "a_fifo"
    os.mkfifo(path)
    return path


LOCATIONS = [
    # (id, command before the location, make(box) -> location, what the message must say)
    ("plan: an existing file", ["plan", NOWHERE, "--out"], _file,
     r"--out .*a_file is a file: a directory is needed"),
    ("plan: /dev/full", ["plan", NOWHERE, "--out"], lambda b: "/dev/full",
     r"/dev/full is a character device"),
    ("plan: /dev/null", ["plan", NOWHERE, "--out"], lambda b: "/dev/null",
     r"/dev/null is a character device"),
    ("plan: empty", ["plan", NOWHERE, "--out"], lambda b: "", r"--out is empty: name a directory"),
    ("plan: blank", ["plan", NOWHERE, "--out"], lambda b: "   ", r"--out is empty"),
    ("plan: below a file", ["plan", NOWHERE, "--out"], lambda b: _file(b) / "x" / "y",
     r"cannot be created: .*a_file is a file"),
    ("plan: a FIFO", ["plan", NOWHERE, "--out"], _fifo, r"a FIFO \(named pipe\): a directory is needed"),
    ("simulate: a directory", ["simulate", NOWHERE, "--out"], lambda b: b.out,
     r"is a directory: a regular file is needed"),
    ("simulate: /dev/full", ["simulate", NOWHERE, "--out"], lambda b: "/dev/full",
     r"/dev/full is a character device"),
    ("simulate: empty", ["simulate", NOWHERE, "--out"], lambda b: "", r"--out is empty: name a file"),
    ("simulate: below a file", ["simulate", NOWHERE, "--out"], lambda b: _file(b) / "t.csv",
     r"its folder .*a_file is a file"),
    ("simulate: a FIFO", ["simulate", NOWHERE, "--out"], _fifo,
     r"a FIFO \(named pipe\): a regular file is needed"),
    ("simulate --plot: a file", ["simulate", NOWHERE, "--plot"], _file, r"--plot .*a_file is a file"),
    ("sweep: an existing file", ["sweep", NOWHERE, "--grid", "final.y=0.3,0.4", "--out"], _file,
     r"is a file"),
    ("sweep: /dev/full", ["sweep", NOWHERE, "--grid", "final.y=0.3,0.4", "--out"], lambda b: "/dev/full",
     r"character device"),
    ("sweep: empty", ["sweep", NOWHERE, "--grid", "final.y=0.3,0.4", "--out"], lambda b: "",
     r"--out is empty"),
    ("track: an existing file", ["track", NOWHERE, "--out"], _file,
     r"--out .*a_file is a file: a directory is needed"),
    ("track: /dev/full", ["track", NOWHERE, "--out"], lambda b: "/dev/full",
     r"/dev/full is a character device"),
    ("track: below a file", ["track", NOWHERE, "--out"], lambda b: _file(b) / "x",
     r"cannot be created: .*a_file is a file"),
    ("sweep: below a file",
     ["sweep", NOWHERE, "--grid", "final.y=0.3,0.4", "--out"], lambda b: _file(b) / "s", r"a_file is a file"),
    ("bench: an existing file", ["bench", "precision", NOWHERE, "--out"], _file, r"is a file"),
    ("bench: empty", ["bench", "precision", NOWHERE, "--out"], lambda b: "", r"--out is empty"),
    ("reproduce: an existing file", ["reproduce", "--out"], _file, r"is a file"),
    ("reproduce: /dev/full", ["reproduce", "--out"], lambda b: "/dev/full", r"character device"),
    ("reproduce: empty", ["reproduce", "--out"], lambda b: "", r"--out is empty"),
]


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="Linux devices")
@pytest.mark.parametrize("command, make, said", [pytest.param(*c[1:], id=c[0]) for c in LOCATIONS])
def test_a_bad_location_is_refused_before_any_work(command, make, said, sandbox):
    """Exit 2 naming the location, before the (missing) scene is even read; nothing created."""
    location = make(sandbox)
    before = sorted(p.name for p in sandbox.root.iterdir())
    got = answer([*command, location]).check(2, said, sandbox)
    assert NOWHERE not in got.err
    assert sorted(p.name for p in sandbox.root.iterdir()) == before


FAULTS = [
    # (id, what fails, errno, what the message must say)
    ("read-only file system", "mkstemp", errno.EROFS, r"is on a read-only file system"),
    ("permission denied", "mkstemp", errno.EACCES, r"permission denied in"),
    ("disk full", "fsync", errno.ENOSPC, r"no space left on the device of"),
    ("quota exhausted", "fsync", errno.EDQUOT, r"disk quota .* is exhausted"),
    ("file-size limit", "fsync", errno.EFBIG, r"file-size limit \(ulimit -f\)"),
    ("an I/O error", "fsync", errno.EIO, r"Input/output error"),
]


@pytest.mark.parametrize("where, code, said", [pytest.param(*c[1:], id=c[0]) for c in FAULTS])
@pytest.mark.parametrize("command", [["plan", NOWHERE], ["simulate", NOWHERE],
                                     ["sweep", NOWHERE, "--grid", "x=1,2"],
                                     ["track", NOWHERE]], ids=["plan", "simulate", "sweep", "track"])
def test_a_location_that_cannot_take_a_write_is_refused_with_the_reason(command, where, code, said, sandbox,
                                                                        monkeypatch):
    """The probe write meets the file system's error (as a read-only or full disk raises it):
    exit 2 with the reason, and the probe file is removed."""
    from nhgait.gaits.files import outputs

    def fail(*args, **kwargs):
        raise OSError(code, os.strerror(code))
    if where == "mkstemp":
        monkeypatch.setattr(outputs.tempfile, "mkstemp", fail)
    else:
        monkeypatch.setattr(outputs.os, "fsync", fail)
    target = sandbox.out / ("t.csv" if command[0] == "simulate" else "o")
    answer([*command, "--out", target]).check(2, said, sandbox)
    assert list(sandbox.out.iterdir()) == []


def test_a_file_size_limit_refuses_the_location_in_a_real_process(sandbox):
    """``ulimit -f`` of 2 kB (the 4 kB probe cannot be written): exit 2 naming the limit."""
    got = run_process([*PLAN, "--out", sandbox.out / "p"], sandbox, file_size=2_000)
    got.check(2, r"the file-size limit \(ulimit -f\) is too small", sandbox)


# ----------------------------------------------------------------------------- sweep stores
def _store_case(kind):
    def make(box):
        d = box.out / "s"
        d.mkdir()
        victim = box.root / "victim.txt"
        victim.write_text("precious")
        if kind == "link":
            (d / "sweep.sqlite").symlink_to(victim)
        elif kind == "wal link":
            (d / "sweep.sqlite-wal").symlink_to(victim)
        elif kind == "solutions link":
            (d / "solutions").symlink_to(box.root)
        elif kind == "directory":
            (d / "sweep.sqlite").mkdir()
        elif kind == "text":
            (d / "sweep.sqlite").write_text("not a database, just text " * 100)
        return d, victim
    return make


STORES = [
    ("sweep.sqlite a link", "link", r"sweep\.sqlite is a symbolic link"),
    ("its journal a link", "wal link", r"sweep\.sqlite-wal is a symbolic link"),
    ("solutions a link", "solutions link", r"solutions is a symbolic link"),
    ("sweep.sqlite a directory", "directory", r"sweep\.sqlite is not a regular file"),
    ("sweep.sqlite a text file", "text", r"sweep\.sqlite is not a sweep store"),
]


@pytest.mark.parametrize("kind, said", [pytest.param(*c[1:], id=c[0]) for c in STORES])
def test_a_store_that_is_not_ours_is_refused_and_left_alone(kind, said, sandbox):
    """A linked store (it turned its target into a database), journal or solutions folder, a
    directory or a text file named sweep.sqlite: exit 2, the link's target unchanged."""
    folder, victim = _store_case(kind)(sandbox)
    answer([*SWEEP, "--grid", "final.y=0.3,0.4", "--out", folder]).check(2, said, sandbox)
    assert victim.read_text() == "precious"


# ----------------------------------------------------------------------------- one writer
HOLDER = textwrap.dedent("""
    import sys
    from nhgait.gaits.files.outputs import output_lock
    with output_lock(sys.argv[1], "nhgait sweep unicycle --grid final.y=0.2:0.6:3"):
        print("HOLDING", flush=True)
        sys.stdin.read()                 # held until the test closes the pipe (or kills it)
""")


@pytest.fixture
def held(sandbox):
    """A directory whose writer lock another process holds (as a first sweep would) for as long
    as the test runs: the holder waits on its stdin, not on a clock."""
    folder = sandbox.out / "shared"
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(folder)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, start_new_session=True)
    assert proc.stdout.readline().strip() == "HOLDING"
    yield folder, proc
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    proc.stdin.close()
    proc.stdout.close()


@pytest.mark.parametrize("command", [SWEEP + ["--grid", "final.y=0.3:0.7:4"], PLAN], ids=["sweep", "plan"])
def test_a_second_writer_is_refused_at_once_naming_the_first(command, held, sandbox):
    """Two sweeps with different grids on one --out lost 40 points silently: the second is now
    refused before any work, with the first one's process id and command."""
    folder, proc = held
    got = answer([*command, "--out", folder])
    got.check(2, rf"is being written by another nhgait run \(process {proc.pid} on .*nhgait sweep unicycle")
    assert not (folder / "sweep.sqlite").exists()


def test_a_lock_left_by_a_killed_writer_is_taken_over(held, sandbox):
    """kill -9 of the writer: the kernel drops its lock; the next writer takes the directory
    and removes the lock file when it is done."""
    from nhgait.gaits.files.outputs import LOCK_NAME, output_lock
    folder, proc = held
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert (folder / LOCK_NAME).exists()               # the file stays, unlocked
    with output_lock(folder, "the next run"):
        assert json.loads((folder / LOCK_NAME).read_text())["pid"] == os.getpid()
    assert not (folder / LOCK_NAME).exists()


def test_two_stores_in_one_process_are_two_writers(tmp_path):
    from nhgait.dynamics.errors import ModelError
    from nhgait.gaits.sweeps.store import SweepStore
    with SweepStore(tmp_path / "s"):
        with pytest.raises(ModelError, match="is being written by another nhgait run"):
            SweepStore(tmp_path / "s")
    with SweepStore(tmp_path / "s") as again:                  # released with the first
        assert again.count() == 0


# ----------------------------------------------------------------------------- nothing lost
def _no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_plan_whose_files_cannot_be_written_keeps_its_solution(sandbox, monkeypatch):
    """The disk fills while the figures are written: exit 1, the summary says what failed; the
    result was written before the figures (issue 40), so solution.json is in place and holds
    the objective the summary printed."""
    from nhgait.gaits.figures import plots
    monkeypatch.setattr(plots, "gait_figure", _no_space)       # in the figures' processes
    got = answer([*PLAN, "--out", sandbox.out / "p"]).check(1, r"figures +NOT WRITTEN: writing .* failed: "
                                                               r"no space left", sandbox)
    objective = float(re.search(r"J = ([-\d.e+]+)", got.out).group(1))
    data = json.loads((sandbox.out / "p" / "solution.json").read_text())
    assert data["objective"] == pytest.approx(objective, rel=1e-6)
    assert data["success"] is True


def _die(*args, **kwargs):
    os._exit(3)


def test_a_plan_whose_figures_process_dies_keeps_its_solution(sandbox, monkeypatch):
    """The figures are drawn in supervised children (``plots.figure_jobs``); one that dies
    without an answer (here: exits in the shape figure) is a failed write, said in one line,
    and solution.json, written before the figures, stays — not a traceback, not a hang, no
    child left."""
    from nhgait.gaits.figures import plots
    from nhgait.ocp.supervision import can_fork
    if not can_fork():
        pytest.skip("the figures run in this process without fork")
    monkeypatch.setattr(plots, "plot_shape_loop", _die)
    answer([*PLAN, "--out", sandbox.out / "p"]).check(
        1, r"NOT WRITTEN: writing .* failed: the figures' process ended without an answer", sandbox)
    assert json.loads((sandbox.out / "p" / "solution.json").read_text())["success"] is True


def test_a_simulation_whose_csv_cannot_be_written_keeps_its_run(sandbox, monkeypatch):
    """The CSV write fails at the end: exit 1 and the run's CSV, 201 samples and a header, in
    the fallback the summary names."""
    from nhgait.dynamics.simulation.trajectory import Trajectory
    to_csv = Trajectory.to_csv
    target = sandbox.out / "t.csv"

    def fail_there(self, path, *args, **kwargs):
        if str(path) == str(target):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        return to_csv(self, path, *args, **kwargs)
    monkeypatch.setattr(Trajectory, "to_csv", fail_there)
    got = answer(["simulate", "unicycle", "--out", target]).check(1, r"NOT WRITTEN: .*no space left", sandbox)
    rescued = re.search(r"the trajectory was saved to (\S+t\.csv)", got.out).group(1)
    assert len(open(rescued).read().splitlines()) == 202


def test_a_sweep_whose_store_fails_keeps_every_point(sandbox, monkeypatch):
    """The store cannot take the second point (disk full): exit 1; the first point stays in the
    store, the second is saved to the fallback the message names; --resume is suggested."""
    from nhgait.gaits.sweeps.store import StoreWriteError, SweepStore
    add, calls = SweepStore.add, []

    def full_after_one(self, record):
        calls.append(record.id)
        if len(calls) == 2:
            raise StoreWriteError(f"cannot write {self.path} (database or disk is full)")
        return add(self, record)
    monkeypatch.setattr(SweepStore, "add", full_after_one)
    out = sandbox.out / "s"
    got = answer([*SWEEP, "--grid", "final.y=0.3,0.4,0.5", "--out", out])
    got.check(1, r"stopped: cannot write .* \(database or disk is full\); 1 points are "
                 r"stored .*--resume", sandbox)
    rescued = re.search(r"saved to (\S+unstored_points\.json)", got.err).group(1)
    (point,) = json.loads(open(rescued).read())
    assert point["id"] == calls[1]
    assert point["answer"]["success"] in (True, False)
    monkeypatch.setattr(SweepStore, "add", add)
    with SweepStore(out, create=False) as store:
        assert store.done_ids() == {calls[0]}


def test_a_result_with_nowhere_to_go_is_printed(tmp_path, monkeypatch, capfd):
    """No fallback folder takes it (TMPDIR and home are files): the text is printed."""
    from types import SimpleNamespace

    from nhgait.gaits.files import outputs
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    monkeypatch.setattr(outputs, "tempfile", SimpleNamespace(gettempdir=lambda: str(blocker)))
    monkeypatch.setattr(outputs.Path, "home", classmethod(lambda cls: blocker))
    said = outputs.rescue("solution.json", {"objective": 0.25}, "solution")
    assert said == "the solution (solution.json) is printed above: no fallback folder could be written"
    printed = capfd.readouterr().out
    assert (json.loads(printed.split("----- solution.json -----")[1].split("----- end")[0])
            == {"objective": 0.25})


@pytest.mark.skipif(not hasattr(os, "memfd_create"), reason="Linux memfd")
def test_a_table_with_nowhere_to_go_is_printed_through_memory(tmp_path, monkeypatch, capfd):
    """A writer that needs a path (the CSV writers) writes into an in-memory file whose text is
    printed; standard output is never reopened (that truncated a redirected one)."""
    from types import SimpleNamespace

    from nhgait.gaits.files import outputs
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    monkeypatch.setattr(outputs, "tempfile", SimpleNamespace(gettempdir=lambda: str(blocker)))
    monkeypatch.setattr(outputs.Path, "home", classmethod(lambda cls: blocker))
    print("a line printed before")
    said = outputs.rescue("t.csv", lambda path: open(path, "w").write("t,x\n0.0,1.5\n"), "trajectory")
    assert "is printed above" in said
    assert (capfd.readouterr().out == "a line printed before\n----- t.csv -----\nt,x\n0.0,1.5\n\n----- end "
                                      "of t.csv -----\n")
