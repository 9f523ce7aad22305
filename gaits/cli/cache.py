"""``nhgait cache [list | clean | stop] [--json]`` (registered by :mod:`nhgait.gaits.cli.main`).

The disk cache (:mod:`nhgait.dynamics.numerics.cache`: ``$NHGAIT_CACHE_DIR``, else the user's
cache directory) and its background builds (:mod:`nhgait.dynamics.numerics.background`):

* ``list`` (the default): the entries — derived models (``*.pkl``), the last verified optimum
  of each task (``*.optimum``: a later plan's first guess, :mod:`nhgait.gaits.planning.plan_memo`),
  compiled libraries (``jit/*.so``), failed builds (``jit/*.failed``), build folders being
  written — with their sizes, the builds waiting in the queue (``builds/*.req``: robot and
  task, flags, estimate, age) and the running builder (its pid and age);
* ``stop``: withdraws every pending build and ends the builder (its compiler killed, its build
  folder removed);
* ``clean``: ``stop``, then removes everything nhgait keeps in the cache directory (only its own
  files: a directory named by ``$NHGAIT_CACHE_DIR`` that holds other files keeps them).

``--json`` prints one JSON object instead of text. Exit status 0.
"""
from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

__all__ = ["add_cache_parser", "cmd_cache", "survey"]

#: a derived model's entry (:func:`nhgait.dynamics.numerics.cache.store`)
ENTRY = re.compile(r"[0-9a-f]{64}\.pkl")
#: a task's last verified optimum (:func:`nhgait.gaits.planning.plan_memo.store_optimum`)
OPTIMUM = re.compile(r"[0-9a-f]{64}\.optimum")


def add_cache_parser(subparsers):
    p = subparsers.add_parser("cache", help="list, clean or stop the model and compile cache and its "
                                            "background builds",
                              description="The model and compile cache: its entries, the optimised "
                                          "builds waiting and the running builder (list), stop them "
                                          "(stop), or empty it (clean).")
    p.add_argument("action", nargs="?", choices=["list", "clean", "stop"], default="list",
                   help="list (default), clean or stop")
    p.add_argument("--json", action="store_true", help="one JSON object instead of text")
    p.set_defaults(func=cmd_cache)
    return p


def _size(path: Path) -> int:
    try:
        if path.is_dir() and not path.is_symlink():
            return sum(_size(p) for p in path.iterdir())
        return path.lstat().st_size
    except OSError:
        return 0


def _files(folder: Path, pattern: str) -> list:
    try:
        return sorted(folder.glob(pattern))
    except OSError:
        return []


def survey(cache: Path) -> dict:
    """What the cache directory ``cache`` holds (module docstring), as a JSON-ready dict."""
    from nhgait.dynamics.numerics import build_queue
    jit, now = cache / "jit", time.time()
    kinds = {"models": [p for p in _files(cache, "*.pkl") if ENTRY.fullmatch(p.name)],
             "optima": [p for p in _files(cache, "*.optimum") if OPTIMUM.fullmatch(p.name)],
             "libraries": _files(jit, "*.so"), "failed builds": _files(jit, "*.failed"),
             "build folders": _files(jit, ".build-*")}
    entries = {kind: {"count": len(paths), "bytes": sum(_size(p) for p in paths)}
               for kind, paths in kinds.items()}
    folder = cache / build_queue.QUEUE_FOLDER
    pending = [{"key": r.key, "slot": r.header.get("slot", ""), "flags": r.header.get("flags", []),
                "estimate_s": r.header.get("estimate_s"), "budget_s": r.header.get("budget_s"),
                "age_s": round(now - r.requested, 1), "requester": r.header.get("requester")}
               for r in (build_queue.pending(folder) if folder.is_dir() else [])]
    info = build_queue.holder(folder) if folder.is_dir() else None
    builder = None if info is None else {"pid": info.pid, "age_s": round(now - info.started, 1)}
    return {"cache": str(cache), "exists": cache.is_dir(), "entries": entries,
            "bytes": sum(e["bytes"] for e in entries.values()), "pending": pending, "builder": builder}


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e5 else f"{n / 1e3:.1f} kB"


def _text(report: dict) -> list:
    lines = [f"cache {report['cache']}" + ("" if report["exists"] else " (not created yet)")]
    for kind, e in report["entries"].items():
        lines.append(f"  {kind:<15} {e['count']:4d}  {_mb(e['bytes'])}")
    lines.append(f"  {'total':<15} {'':4}  {_mb(report['bytes'])}")
    pending, builder = report["pending"], report["builder"]
    lines.append(f"  {len(pending)} pending build{'s' if len(pending) != 1 else ''}"
                 + (":" if pending else ""))
    for p in pending:
        lines.append(f"    {p['key'][:12]}  {p['slot']}, about "
                     f"{p['estimate_s'] or 0:.0f} s (at most {p['budget_s'] or 0:.0f} s), asked "
                     f"{p['age_s']:.0f} s ago")
    lines.append(f"  builder pid {builder['pid']}, running for {builder['age_s']:.0f} s" if builder
                 else "  no builder running")
    if pending or builder:
        lines.append("  (nhgait cache stop ends them; plans ask for none with --no-background-build or "
                     "NHGAIT_BACKGROUND_BUILDS=0)")
    return lines


def clean(cache: Path) -> int:
    """Remove nhgait's own files from the cache directory ``cache`` (module docstring); how many
    entries (files or folders) were removed. The directory itself goes when it is left empty."""
    from nhgait.dynamics.numerics.build_queue import QUEUE_FOLDER
    removed = 0
    for path in [*(p for p in _files(cache, "*.pkl") if ENTRY.fullmatch(p.name)),
                 *(p for p in _files(cache, "*.optimum") if OPTIMUM.fullmatch(p.name)),
                 *_files(cache, ".tmp-*"), cache / "jit", cache / QUEUE_FOLDER]:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        elif path.exists() or path.is_symlink():
            path.unlink(missing_ok=True)
        else:
            continue
        removed += 1
    try:
        cache.rmdir()
    except OSError:
        pass
    return removed


def cmd_cache(args) -> int:
    from nhgait.dynamics.numerics.background import stop_builds
    from nhgait.dynamics.numerics.cache import cache_dir
    cache = cache_dir()
    report = {}
    if args.action in ("stop", "clean"):
        withdrawn, pid = stop_builds(cache)
        report["stopped"] = {"withdrawn": withdrawn, "builder": pid}
    if args.action == "clean":
        report["cleaned"] = {"removed": clean(cache)}
    report = {**survey(cache), **report}
    if args.json:
        print(json.dumps(report, indent=1))
        return 0
    if "stopped" in report:
        s = report["stopped"]
        print(f"stopped: {s['withdrawn']} pending build(s) withdrawn"
              + (f", builder pid {s['builder']} ended" if s["builder"] else ""))
    if "cleaned" in report:
        print(f"cleaned: {report['cleaned']['removed']} entries removed")
    print("\n".join(_text(report)))
    return 0
