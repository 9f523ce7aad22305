"""Where sweep points run: one small ``concurrent.futures``-style interface, three back ends.

Every back end has ``submit(fn, *args) -> concurrent.futures.Future``, ``workers`` (how
many points run at once), ``chain`` (how many points of a continuation chain one task should
carry: 1 where a task costs nothing, 4 on Dask, whose fixed cost per task — scheduler, worker
and client messages, several milliseconds on a small machine — is then shared by 4 solves),
``describe()`` and ``close()`` (also a context manager). ``fn`` and
``args`` must be picklable with :mod:`pickle` (functions of an importable module, plain
data): nothing live crosses a process boundary. A worker that dies fails the future of the
task it was running — and only that one — with :class:`WorkerDied`; the sweep driver retries
that task's points once (a chain's points one by one).

* :class:`SerialBackend` — in this process, one point at a time (debugging, tiny sweeps).
* :class:`ProcessPool` — the default: one process per core (``os.process_cpu_count`` /
  the CPU affinity), started with ``spawn`` so that no CasADi or thread state is inherited.
  Unlike :class:`concurrent.futures.ProcessPoolExecutor` (where one dead child breaks the
  whole pool and every pending future), each worker has its own pipe and the pool watches
  each process: a dead worker fails its own point and is replaced.
* :class:`DaskBackend` — a ``dask.distributed`` :class:`~distributed.Client` on an existing
  scheduler (``ADDRESS``) or on a :class:`~distributed.LocalCluster` it starts on loopback
  (``local:N``: N single-threaded worker processes under nannies, which restart a killed
  worker). The local cluster's scheduler runs with ``allowed_failures=0`` so a worker death
  is reported at once (``KilledWorker``) and the driver's own retry-once rule applies; an
  external scheduler applies its own ``distributed.scheduler.allowed-failures`` first.
  Dask is optional (``pip install nhgait[dask]``).
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import pickle
import shutil
import tempfile
import threading
import traceback
from collections import deque
from multiprocessing.connection import wait

from nhgait.ocp import ProblemError

__all__ = ["WorkerDied", "SerialBackend", "ProcessPool", "DaskBackend", "make_backend", "backend_problems",
           "default_workers", "dask_available", "warm_up", "import_modules"]


class WorkerDied(RuntimeError):
    """The process running a point ended (killed, crashed, out of memory) before it answered."""


def default_workers() -> int:
    """The cores this process may use (CPU affinity when the OS tells it), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return max(1, os.cpu_count() or 1)


#: what a worker imports to solve and verify a point (the verification's scipy.integrate alone
#: takes ≈ 0.5 s: a third of a cold centre point when it is not imported before)
WORKER_MODULES = ("nhgait.gaits.planner", "nhgait.gaits.sweeps.point", "scipy.integrate")


def import_modules(names=WORKER_MODULES) -> int:
    """Import ``names`` in this process and return its id (run on each worker by :func:`warm_up`)."""
    import importlib
    for name in names:
        importlib.import_module(name)
    return os.getpid()


def warm_up(backend, names=WORKER_MODULES) -> list:
    """Have every worker import ``names`` (e.g. before timing a sweep); returns their process ids
    (a worker may answer twice on a back end that does not spread the calls)."""
    futures = [backend.submit(import_modules, tuple(names)) for _ in range(backend.workers)]
    return [f.result() for f in futures]


def dask_available() -> bool:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


class _Backend:
    chain = 1
    workers = 1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:  # pragma: no cover - trivial
        pass


# ----------------------------------------------------------------------------- serial
class SerialBackend(_Backend):
    """Run each point at submission, in this process (exceptions land in the future)."""

    workers = 1

    def submit(self, fn, *args) -> cf.Future:
        future = cf.Future()
        try:
            future.set_result(fn(*args))
        except Exception as exc:  # noqa: BLE001 - handed to the caller through the future
            future.set_exception(exc)
        return future

    def describe(self) -> str:
        return "serial (this process)"


# ----------------------------------------------------------------------------- process pool
def _worker_main(conn, parent: int | None = None) -> None:
    """A pool worker: receive (fn, args), answer ("ok", value) or ("error", exception text).
    On Linux it dies with the thread of ``parent`` that started it (``PR_SET_PDEATHSIG``): a
    driver that ends at once on SIGTERM (:mod:`nhgait.gaits.cli.stopping`) leaves no worker
    solving on; its solver attempts, supervised children of its own, go with it."""
    _die_with(parent)
    while True:
        try:
            message = conn.recv()
        except EOFError:
            return
        if message is None:
            return
        fn, args = message
        try:
            answer = ("ok", fn(*args))
        except Exception as exc:  # noqa: BLE001 - sent back to the driver with its traceback
            answer = ("error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=8)}")
        try:
            conn.send(answer)
        except Exception as exc:  # noqa: BLE001 - an answer that cannot be pickled
            conn.send(("error", f"the answer cannot be sent back ({type(exc).__name__}: {exc})"))


def _die_with(parent: int | None) -> None:
    """Ctrl-C is the driver's to handle (it closes the pool); on Linux, SIGKILL when the
    driver's thread that started this worker ends."""
    import signal
    import sys
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent is None or not sys.platform.startswith("linux"):
        return
    import ctypes
    ctypes.CDLL(None).prctl(1, signal.SIGKILL)          # PR_SET_PDEATHSIG
    if os.getppid() != parent:                          # the driver ended before that
        os._exit(1)


#: set in each worker's environment unless the user set them: one point per core, so the
#: linear-algebra libraries must not start threads of their own (Dask's nannies do the same)
SINGLE_THREADED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class _Slot:
    """One worker process, its pipe and the future of the point it runs (None when idle)."""

    def __init__(self, ctx):
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker_main, args=(child, os.getpid()), daemon=True)
        added = {k: v for k, v in SINGLE_THREADED.items() if k not in os.environ}
        os.environ.update(added)          # a spawned child copies the environment at start
        try:
            self.process.start()
        finally:
            for key in added:
                os.environ.pop(key, None)
        child.close()
        self.future: cf.Future | None = None


class ProcessPool(_Backend):
    """``workers`` spawned processes, each solving one point at a time (see the module docstring)."""

    def __init__(self, workers: int | None = None):
        self.workers = int(workers or default_workers())
        if self.workers < 1:
            raise ProblemError([f"workers must be ≥ 1, got {workers}"], title="invalid back end")
        self._ctx = multiprocessing.get_context("spawn")
        self._slots = [_Slot(self._ctx) for _ in range(self.workers)]
        self._pending: deque = deque()
        self._lock = threading.Lock()
        self._wake_r, self._wake_w = self._ctx.Pipe(duplex=False)
        self._closed = False
        self._thread = threading.Thread(target=self._loop, name="nhgait-pool", daemon=True)
        self._thread.start()

    def describe(self) -> str:
        return f"local process pool ({self.workers} worker{'s' if self.workers != 1 else ''})"

    def pids(self) -> list:
        """The worker processes' ids (for tests and monitoring)."""
        return [s.process.pid for s in self._slots]

    def submit(self, fn, *args) -> cf.Future:
        future = cf.Future()
        with self._lock:
            if self._closed:
                raise RuntimeError("the process pool is closed")
            self._pending.append((future, fn, args))
        self._wake_w.send(None)
        return future

    def _dispatch(self) -> None:
        with self._lock:
            for slot in self._slots:
                if slot.future is None and self._pending:
                    future, fn, args = self._pending.popleft()
                    if not future.set_running_or_notify_cancel():
                        continue
                    try:
                        slot.conn.send((fn, args))
                        slot.future = future
                    except Exception as exc:  # noqa: BLE001 - unpicklable arguments, a dead pipe
                        future.set_exception(exc)

    def _finish(self, slot: _Slot) -> None:
        future, slot.future = slot.future, None
        try:
            kind, value = slot.conn.recv()
        except (EOFError, OSError):
            slot.process.join(timeout=5)
            future.set_exception(WorkerDied(f"worker process {slot.process.pid} died "
                                            f"(exit code {slot.process.exitcode}) while solving this point"))
            self._slots[self._slots.index(slot)] = _Slot(self._ctx)
            return
        if kind == "ok":
            future.set_result(value)
        else:
            future.set_exception(RuntimeError(value))

    def _loop(self) -> None:
        while True:
            self._dispatch()
            busy = [s for s in self._slots if s.future is not None]
            ready = wait([self._wake_r] + [s.conn for s in busy] + [s.process.sentinel for s in busy])
            if self._wake_r in ready:
                while self._wake_r.poll():
                    self._wake_r.recv()
                if self._closed:
                    return
            for slot in busy:
                if slot.conn in ready or slot.process.sentinel in ready:
                    if slot.conn.poll() or not slot.process.is_alive():
                        self._finish(slot)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            pending, self._pending = list(self._pending), deque()
        for future, _, _ in pending:
            future.cancel()
        self._wake_w.send(None)
        self._thread.join(timeout=10)
        for slot in self._slots:
            if slot.future is not None:     # closed mid-point (an interrupt): its answer is not wanted
                slot.future.cancel() or slot.future.set_exception(RuntimeError("the process pool was closed"))
                slot.process.terminate()    # SIGTERM: it dies at once, its supervised solvers with it
                continue
            try:
                slot.conn.send(None)
            except OSError:
                continue          # the worker has exited (its end of the pipe is closed): joined below
        for slot in self._slots:
            slot.process.join(timeout=5)
            if slot.process.is_alive():
                slot.process.terminate()
                slot.process.join(timeout=5)


# ----------------------------------------------------------------------------- dask
def _run_pickled(blob: bytes) -> bytes:
    """Run on a Dask worker: ``fn(*args)`` from the pickled (fn, args), the answer pickled."""
    fn, args = pickle.loads(blob)
    return pickle.dumps(fn(*args), protocol=pickle.HIGHEST_PROTOCOL)


class DaskBackend(_Backend):
    """Points as tasks of a ``dask.distributed`` client (see the module docstring).

    ``scheduler``: an address (``tcp://host:8786``) or ``local:N`` for a
    :class:`~distributed.LocalCluster` of N single-threaded worker processes on 127.0.0.1.
    """

    chain = 4

    def __init__(self, scheduler: str):
        if not dask_available():
            raise ProblemError(["--scheduler needs Dask distributed, which is not installed "
                                "(pip install 'nhgait[dask]')"], title="Dask not available")
        from distributed import Client, LocalCluster
        self.cluster, self.scratch = None, None
        self._futures: dict = {}
        self._lock = threading.Lock()
        if scheduler.startswith("local:"):
            n = scheduler.partition(":")[2]
            if not n.isdigit() or int(n) < 1:
                raise ProblemError([f"--scheduler {scheduler!r}: local:N needs a whole number N ≥ "
                                    "1 of workers"],
                                   title="invalid back end")
            self.scratch = tempfile.mkdtemp(prefix="nhgait-dask-")   # the workers' own, removed on close
            self.cluster = LocalCluster(n_workers=int(n), threads_per_worker=1, processes=True,
                                        host="127.0.0.1", dashboard_address=None,
                                        local_directory=self.scratch,
                                        scheduler_kwargs={"allowed_failures": 0})
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise ProblemError([f"--scheduler {scheduler!r}: cannot connect ({exc})"],
                                   title="invalid back end") from None
        self.scheduler = scheduler
        info = self.client.scheduler_info()
        self.workers = max(1, sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()))

    def describe(self) -> str:
        where = "LocalCluster on 127.0.0.1" if self.cluster is not None else self.client.scheduler.address
        return f"Dask distributed ({where}, {self.workers} worker thread{'s' if self.workers != 1 else ''})"

    def submit(self, fn, *args) -> cf.Future:
        from distributed import KilledWorker
        future = cf.Future()
        # one opaque bytes argument: Dask neither walks the nested job looking for futures
        # nor re-encodes the answer (measured: 37 → 21 ms per round trip for a P2 point)
        task = self.client.submit(_run_pickled, pickle.dumps((fn, args), protocol=pickle.HIGHEST_PROTOCOL),
                                  pure=False)
        with self._lock:
            self._futures[task.key] = task        # a Dask future must stay referenced to run

        def done(task):
            with self._lock:
                self._futures.pop(task.key, None)
            try:
                future.set_result(pickle.loads(task.result()))
            except KilledWorker as exc:
                future.set_exception(WorkerDied(f"Dask worker {exc.last_worker.address} died while solving "
                                                "this point"))
            except Exception as exc:  # noqa: BLE001 - the task's own error, or a cancelled task
                future.set_exception(exc)

        task.add_done_callback(done)
        return future

    def worker_pids(self) -> dict:
        """Worker address → process id (for tests and monitoring)."""
        return self.client.run(os.getpid)

    def close(self) -> None:
        with self._lock:
            pending, self._futures = list(self._futures.values()), {}
        for task in pending:
            task.cancel()
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        if self.scratch is not None:       # not /tmp/dask-scratch-space: nothing left behind
            shutil.rmtree(self.scratch, ignore_errors=True)


def backend_problems(scheduler: str | None = None, workers: int | None = None) -> list:
    """What is wrong with a ``--scheduler``/``--workers`` request (checked before any work)."""
    if scheduler and workers:
        return ["give either --scheduler or --workers: a Dask cluster has its own workers"]
    from ..planning.options import whole_number
    if not scheduler and workers is not None and not (whole_number(workers) and workers >= 0):
        return [f"--workers must be ≥ 0 (a whole number of worker processes), got {workers!r}"]
    return []


def make_backend(scheduler: str | None = None, workers: int | None = None):
    """The back end for ``--scheduler``/``--workers``: a Dask client when a scheduler is
    given, else the local process pool (``workers`` None: one per core; 0: serial, in this
    process)."""
    problems = backend_problems(scheduler, workers)
    if problems:
        raise ProblemError(problems, title="invalid back end")
    if scheduler:
        return DaskBackend(scheduler)
    if workers == 0:
        return SerialBackend()
    return ProcessPool(workers)
