"""The sweep store: one SQLite file (``DIR/sweep.sqlite``) with one row per finished grid point.

Tables
------
``meta`` (key TEXT, value JSON): ``format``, ``scene`` (source and SHA-256 of its text),
``task`` (the base ``[task]`` table), ``grid`` (:meth:`Grid.to_dict`), ``options``,
``created``, ``nhgait``.

``points``: one row per grid point, written by the driver (only) as soon as the point
finishes, each in its own committed transaction — an interrupted sweep keeps every row it
wrote, and ``resume`` solves only the points without one. Columns (see :class:`PointRecord`):
``id`` (indices joined by ``-``, the primary key), ``idx`` and ``axis_values`` (JSON), the
point's full ``task`` table and parameter values ``params`` (JSON), ``success``, ``status``,
``message``, ``objective``, ``iterations`` (of the solve that produced the solution),
``total_iterations`` (every solve the point needed: a failed warm start, the guesses tried),
``solve_time_s`` (Ipopt), ``wall_time_s`` (the
whole point in its worker: set-up, solve, verification), ``verification_error`` (max
|z_sim − z| of the re-simulation), ``constraint_violation``, ``start`` (``cold``,
``warm`` or ``cold after warm failed``), ``warm_from`` (the parent point's id),
``attempts`` (1, or 2 after a worker died), ``worker``, ``solution_path`` (relative to DIR:
``solutions/<id>.json``, the full solution) and ``finished_at`` (UTC ISO time).

One writer per store: an open store holds the directory's writer lock
(:func:`nhgait.gaits.files.outputs.output_lock`; ``lock=False`` when the caller holds it already),
so a second sweep on the same ``--out`` is refused at once, naming the first. A store file, a
journal or a ``solutions`` folder that is a symbolic link is refused (writing through it would
turn the link's target into a database), and so is a file that is not an SQLite database. A
write that fails while the sweep runs (disk full, folder removed) raises
:class:`StoreWriteError`: the points already stored stay, the driver saves the unstored
answers to a fallback (:func:`nhgait.gaits.files.outputs.rescue`) and ``--resume`` continues.
"""
from __future__ import annotations

import contextlib
import json
import math
import os
import sqlite3
import tempfile
from dataclasses import dataclass, fields
from datetime import datetime, timezone
from pathlib import Path

from nhgait.ocp import ProblemError

__all__ = ["SweepStore", "PointRecord", "StoreWriteError", "STORE_NAME", "FORMAT"]

STORE_NAME = "sweep.sqlite"
FORMAT = 1
#: what makes a sweep the same sweep on --resume
IDENTITY = ("scene", "task", "params", "options", "grid")
#: the store's files besides sweep.sqlite (SQLite's journals) and the solutions folder: none may be a link
_COMPANIONS = (STORE_NAME + "-wal", STORE_NAME + "-shm", STORE_NAME + "-journal", "solutions")


class StoreWriteError(RuntimeError):
    """A write to the store failed while the sweep ran (disk full, folder removed, read-only):
    the message says why; the points stored before stay."""


@dataclass(frozen=True)
class PointRecord:
    """One row of the ``points`` table (units: seconds; objective in the task's units)."""

    id: str
    idx: tuple
    axis_values: dict
    task: dict
    params: dict
    success: bool
    status: str
    message: str = ""
    objective: float = math.nan
    iterations: int = 0
    total_iterations: int = 0
    solve_time_s: float = math.nan
    wall_time_s: float = math.nan
    verification_error: float = math.nan
    constraint_violation: float = math.nan
    start: str = ""
    warm_from: str | None = None
    attempts: int = 1
    worker: str = ""
    solution_path: str | None = None
    finished_at: str = ""


_JSON = ("idx", "axis_values", "task", "params")
_REAL = ("objective", "solve_time_s", "wall_time_s", "verification_error", "constraint_violation")
_COLUMNS = tuple(f.name for f in fields(PointRecord))
_TYPES = {"success": "INTEGER NOT NULL", "iterations": "INTEGER", "total_iterations": "INTEGER",
          "attempts": "INTEGER NOT NULL",
          **{c: "REAL" for c in _REAL}, **{c: "TEXT NOT NULL" for c in ("idx", "axis_values", "task",
                                                                        "params",
                                                                          "status")}}


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _sql_value(name, value):
    if name in _JSON:
        return json.dumps(list(value) if name == "idx" else value, sort_keys=True)
    if name in _REAL:
        return None if value is None or not math.isfinite(float(value)) else float(value)
    if name == "success":
        return int(bool(value))
    return value


def _from_sql(name, value):
    if name in _JSON:
        out = json.loads(value)
        return tuple(out) if name == "idx" else out
    if name in _REAL:
        return math.nan if value is None else float(value)
    if name == "success":
        return bool(value)
    return value


class SweepStore:
    """The store of one sweep directory (see the module docstring). Use as a context manager."""

    def __init__(self, directory, *, create: bool = True, lock: bool = True):
        from ..files.outputs import output_lock
        self.directory = Path(directory)
        self.path = self.directory / STORE_NAME
        if not create and not self.path.exists():
            raise ProblemError([f"{self.directory} holds no sweep ({STORE_NAME} not found)"],
                               title="no sweep")
        self._exit = contextlib.ExitStack()
        if create and lock:
            self._exit.enter_context(output_lock(self.directory, f"nhgait sweep --out {self.directory}"))
        try:
            self._refuse_links()
            if create:
                self.directory.mkdir(parents=True, exist_ok=True)
                (self.directory / "solutions").mkdir(exist_ok=True)
            self._db = self._connect(create)
        except BaseException:
            self._exit.close()
            raise

    def _refuse_links(self) -> None:
        """A store file, journal or solutions folder that is a link or not a regular file is refused."""
        problems = []
        for name in (STORE_NAME, *_COMPANIONS):
            path = self.directory / name
            if path.is_symlink():
                problems.append(f"{path} is a symbolic link: nhgait does not write a sweep through links "
                                "(the link's target would become part of the store)")
            elif name != "solutions" and path.exists() and not path.is_file():
                problems.append(f"{path} is not a regular file")
        if problems:
            raise ProblemError(problems, title="invalid sweep directory")

    def _connect(self, create: bool) -> sqlite3.Connection:
        """The open database with its tables (a file that is not an SQLite database is refused)."""
        db = sqlite3.connect(self.path, timeout=30)
        try:
            db.execute("PRAGMA journal_mode=WAL")
            db.execute("PRAGMA synchronous=FULL")
            columns = ", ".join(f"{c} {_TYPES.get(c, 'TEXT')}" + (" PRIMARY KEY" if c == "id" else "")
                                for c in _COLUMNS)
            with db:
                db.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
                db.execute(f"CREATE TABLE IF NOT EXISTS points ({columns})")
        except sqlite3.DatabaseError as exc:
            db.close()
            raise ProblemError([f"{self.path} is not a sweep store ({exc}): choose another --out"],
                               title="invalid sweep directory") from None
        return db

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        try:
            self._db.close()
        finally:
            self._exit.close()

    # ------------------------------------------------------------------ meta
    @property
    def meta(self) -> dict:
        return {k: json.loads(v) for k, v in self._db.execute("SELECT key, value FROM meta")}

    def start(self, meta: dict, *, resume: bool) -> None:
        """Record ``meta`` for a new sweep, or check it against the stored one on ``resume``.

        A new sweep refuses a directory that already holds points; a resumed one refuses a
        different scene, task, parameters, options or grid (:data:`IDENTITY`; every difference
        listed) and refreshes the descriptive entries (units, labels).
        """
        stored = self.meta
        if not resume:
            if self.count():
                raise ProblemError([f"{self.directory} already holds a sweep with {self.count()} finished "
                                    "points: use --resume to continue it, or another --out directory"],
                                   title="sweep directory in use")
            with self._db:
                self._db.execute("DELETE FROM meta")
                self._db.executemany("INSERT INTO meta VALUES (?, ?)",
                                     [(k, json.dumps(v, sort_keys=True)) for k, v in
                                      {**meta, "format": FORMAT, "created": _now()}.items()])
            return
        if not stored:
            raise ProblemError([f"--resume: {self.directory} holds no sweep to resume"],
                               title="nothing to resume")
        problems = []
        if stored.get("format") != FORMAT:
            problems.append(f"the store has format {stored.get('format')}, this nhgait writes {FORMAT}")
        for key, value in meta.items():
            if key not in IDENTITY:        # units, labels: descriptive, refreshed below
                continue
            now = json.loads(json.dumps(value, sort_keys=True))
            if now != stored.get(key):
                problems.append(f"--resume: the {key} differs from the stored sweep's "
                                f"({'; '.join(_differences(stored.get(key), now, key))})")
        if problems:
            raise ProblemError(problems, title="cannot resume this sweep")
        with self._db:
            self._db.executemany("INSERT OR REPLACE INTO meta VALUES (?, ?)",
                                 [(k, json.dumps(v, sort_keys=True)) for k, v in meta.items()
                                  if k not in IDENTITY])

    # ------------------------------------------------------------------ rows
    def write_solution(self, point_id: str, solution: dict) -> str:
        """Write a point's full solution atomically; returns its path relative to the directory."""
        rel, tmp = f"solutions/{point_id}.json", None
        try:
            fd, tmp = tempfile.mkstemp(dir=self.directory / "solutions", prefix=".tmp-", suffix=".json")
            with os.fdopen(fd, "w") as fh:
                fh.write(json.dumps(solution))       # one shot: the C encoder (json.dump streams in Python)
            os.replace(tmp, self.directory / rel)
            tmp = None
        except OSError as exc:
            raise StoreWriteError(f"cannot write {self.directory / rel} ({exc.strerror or exc})") from None
        finally:
            if tmp is not None:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
        return rel

    def add(self, record: PointRecord) -> None:
        """Insert (or replace) one finished point, committed at once."""
        values = [_sql_value(c, getattr(record, c)) for c in _COLUMNS]
        if not record.finished_at:
            values[_COLUMNS.index("finished_at")] = _now()
        try:
            with self._db:
                self._db.execute(f"INSERT OR REPLACE INTO points ({', '.join(_COLUMNS)}) "
                                 f"VALUES ({', '.join('?' * len(_COLUMNS))})", values)
        except sqlite3.OperationalError as exc:       # disk full, read-only, removed
            raise StoreWriteError(f"cannot write {self.path} ({exc})") from None

    def count(self) -> int:
        return int(self._db.execute("SELECT COUNT(*) FROM points").fetchone()[0])

    def done_ids(self) -> set:
        return {r[0] for r in self._db.execute("SELECT id FROM points")}

    def records(self) -> list:
        """Every stored :class:`PointRecord`, in grid order."""
        rows = self._db.execute(f"SELECT {', '.join(_COLUMNS)} FROM points")
        out = [PointRecord(**{c: _from_sql(c, v) for c, v in zip(_COLUMNS, row, strict=True)})
               for row in rows]
        return sorted(out, key=lambda r: r.idx)

    def load_solution(self, record: PointRecord) -> dict | None:
        if not record.solution_path:
            return None
        path = self.directory / record.solution_path
        try:
            return json.loads(path.read_text())
        except (OSError, ValueError):
            return None


def _differences(stored, now, path: str, limit: int = 5) -> list:
    """Where ``now`` differs from ``stored`` (JSON values): "path: stored A, now B" for each
    differing entry of nested tables, at most ``limit`` (a task's whole table cut at 200
    characters hid the difference after a shared prefix)."""
    if isinstance(stored, dict) and isinstance(now, dict):
        out = []
        for k in sorted(set(stored) | set(now)):
            if stored.get(k) != now.get(k):
                out += _differences(stored.get(k), now.get(k), f"{path}.{k}", limit)
        return out[:limit]
    before, after = (json.dumps(v, sort_keys=True)[:80] for v in (stored, now))
    return [f"{path}: stored {before}, now {after}"]
