"""Background builds bounded and accountable, measured from the process table (issue 40).

    python experiments/bench_builders.py [--plans 20] [--json out.json]

1. **A designer's session**: ``--plans`` cold ``nhgait plan`` processes, one after the other, on
   four robots in turns (``unicycle``, ``snakeboard``, ``examples/car.toml``,
   ``examples/rotor_sleigh.toml``) with ``--set`` edits (the horizon, a final position), all in
   one fresh cache, builds on. A sampler thread reads ``/proc`` every 50 ms and counts the
   builder processes of that cache. Reported: the most builders alive at one sample; how long
   the builder lived after the last plan returned, and after the last library it built landed
   (its record's time) — "none alive once the last build's compile time has passed"; the
   builds asked for, built and dropped as stale.
2. **A deleted cache**: a cold plan whose compiler is slowed (``$NHGAIT_CC`` = a wrapper that
   sleeps before it runs gcc, so the build is surely running); the cache folder is removed
   while the builder waits for its compiler; the time until neither the builder nor its
   compiler is left.
3. **SIGHUP to a cold plan**: a cold plan in its own session, sent SIGHUP while its builder
   compiles; its exit status and the processes of the plan, the builder and the compiler left
   2 s after the plan ended (the goal: none), and the time until none was left.
4. **SIGTERM and SIGHUP to a builder**: the time until the builder and its compiler are gone.

Times are wall seconds on this machine, at its load (printed); run on a quiet machine for the
docs' numbers.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: (scene, gait or None, --set edits in turn)
ROBOTS = [("unicycle", "parallel-park",
           ["horizon=2.0", "horizon=2.2", "final.y=0.45", "horizon=2.4", "final.y=0.55"]),
          ("snakeboard", "forward",
           ["horizon=6.2", "horizon=6.0", "final.x=0.9", "horizon=6.4", "final.x=1.1"]),
          (str(ROOT / "examples" / "car.toml"), None,
           ["horizon=3.2", "horizon=3.4", "final.y=0.7", "horizon=3.6", "final.y=0.9"]),
          (str(ROOT / "examples" / "rotor_sleigh.toml"), None,
           ["horizon=9.0", "horizon=9.5", "final.x=0.9", "horizon=10.5", "final.x=1.1"])]
BUILDER = b"nhgait.dynamics.numerics.builder"


def _processes() -> dict:
    """pid → (ppid, session, state, cmdline bytes) of every process."""
    table = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            stat = Path(entry.path, "stat").read_text().rsplit(")", 1)[1].split()
            cmdline = Path(entry.path, "cmdline").read_bytes()
        except (OSError, IndexError):
            continue
        table[int(entry.name)] = (int(stat[1]), int(stat[3]), stat[0], cmdline)
    return table


def builders(cache: Path, table: dict | None = None) -> list:
    """The live builder processes of ``cache``."""
    table = _processes() if table is None else table
    mark = str(cache).encode()
    found = {pid: ppid for pid, (ppid, _, state, cmd) in table.items()
             if BUILDER in cmd and mark in cmd and state not in ("Z", "X")}
    return [pid for pid, ppid in found.items() if ppid not in found]    # not a compiler being forked


def descendants(pids, table: dict) -> list:
    """The live processes descended from ``pids`` (and those themselves)."""
    children: dict = {}
    for pid, (ppid, _, state, _) in table.items():
        if state not in ("Z", "X"):
            children.setdefault(ppid, []).append(pid)
    found, stack = [], list(pids)
    while stack:
        pid = stack.pop()
        if pid in table and table[pid][2] not in ("Z", "X"):
            found.append(pid)
        stack.extend(children.get(pid, ()))
    return found


class Sampler(threading.Thread):
    """Counts the builders of ``cache`` every ``every`` s: ``samples`` [(t, n)]."""

    def __init__(self, cache: Path, every: float = 0.05):
        super().__init__(daemon=True)
        self.cache, self.every, self.samples, self.done = cache, every, [], threading.Event()

    def run(self):
        while not self.done.is_set():
            self.samples.append((time.monotonic(), len(builders(self.cache))))
            self.done.wait(self.every)


def _nhgait() -> list:
    exe = Path(sys.executable).with_name("nhgait")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "nhgait.gaits.cli.main"]


def _plan_args(scene, gait, edit, out) -> list:
    return [*_nhgait(), "plan", scene, *(["--gait", gait] if gait else []), "--set", edit, "--no-gif",
            "--quiet", "--out", str(out)]


def session(plans: int, work: Path, drain_s: float = 1800.0) -> dict:
    """Part 1 (module docstring)."""
    cache = work / "session-cache"
    env = {**os.environ, "NHGAIT_CACHE_DIR": str(cache), "NHGAIT_BACKGROUND_BUILDS": "1"}
    sampler = Sampler(cache)
    sampler.start()
    asked, wall = [], []
    for k in range(plans):
        scene, gait, edits = ROBOTS[k % len(ROBOTS)]
        edit = edits[(k // len(ROBOTS)) % len(edits)]
        out = work / f"plan-{k}"
        t0 = time.monotonic()
        proc = subprocess.run(_plan_args(scene, gait, edit, out), env=env, capture_output=True, text=True)
        wall.append(time.monotonic() - t0)
        later = {}
        try:
            settings = json.loads((out / "solution.json").read_text())["settings"]
            later = (settings.get("compile") or {}).get("later") or {}
        except (OSError, ValueError, KeyError):
            pass
        asked.append({"plan": k, "scene": Path(scene).stem, "edit": edit, "status": proc.returncode,
                      "state": later.get("state"), "key": later.get("key"), "pid": later.get("pid"),
                      "estimate_s": later.get("estimate_s"), "budget_s": later.get("budget_s")})
        print(f"  plan {k + 1}/{plans} {Path(scene).stem} --set {edit}: exit {proc.returncode}, "
              f"{wall[-1]:.1f} s, build {later.get('state')} (builder {later.get('pid')})", file=sys.stderr)
    last_exit = time.monotonic()
    deadline = last_exit + drain_s
    while builders(cache) and time.monotonic() < deadline:
        time.sleep(0.05)
    gone = time.monotonic()
    still = len(builders(cache))               # alive at the end of the wait: a builder past its budgets
    sampler.done.set()
    sampler.join()
    jit = cache / "jit"
    asked_keys = {a["key"] for a in asked if a["state"] in ("started", "queued")}
    records = sorted((p.stat().st_mtime, p) for p in jit.glob("*.json") if p.stem in asked_keys)
    built = {p.stem for _, p in records}
    last_landed_ago = time.time() - records[-1][0] if records else None
    lingered = (gone - time.monotonic() + last_landed_ago) if last_landed_ago is not None else None
    compile_s = [json.loads(p.read_text()).get("compile_s") for _, p in records if p.stem in asked_keys]
    shutil.rmtree(cache, ignore_errors=True)
    return {"plans": plans, "plan_wall_s": [round(w, 1) for w in wall],
            "max_builders_alive": max((n for _, n in sampler.samples), default=0),
            "samples": len(sampler.samples),
            "builder_after_last_plan_s": round(gone - last_exit, 2), "builders_alive_after_wait": still,
            "budgets_of_pending_s": [a["budget_s"] for a in asked if a["state"] in ("started", "queued")],
            "builder_after_last_library_s": None if lingered is None else round(max(lingered, 0.0), 2),
            "builds_asked": len(asked_keys), "builds_built": len(built),
            "builds_dropped_or_unbuilt": len(asked_keys - built),
            "compile_s": compile_s, "asked": asked}


def _slow_compiler(folder: Path, seconds: float) -> Path:
    cc = shutil.which("gcc") or shutil.which("cc")
    script = folder / "slowcc.sh"
    script.write_text(f"#!/bin/sh\necho $$ >> '{folder}/compilers'\nsleep {seconds}\nexec '{cc}' \"$@\"\n")
    script.chmod(0o700)
    return script


def _cold_plan_with_builder(work: Path, name: str, session_of_its_own: bool = True):
    """A cold snakeboard plan (slow compiler), once its builder runs a compiler: (proc, cache,
    builder pid)."""
    cache = work / f"{name}-cache"
    folder = work / name
    folder.mkdir()
    env = {**os.environ, "NHGAIT_CACHE_DIR": str(cache), "NHGAIT_BACKGROUND_BUILDS": "1",
           "NHGAIT_CC": str(_slow_compiler(folder, 120))}
    args = [*_nhgait(), "plan", "snakeboard", "--gait", "forward", "--no-gif", "--quiet",
            "--max-guesses", "12",
            "--time-limit", "600", "--out", str(folder / "out")]
    proc = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=session_of_its_own)
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline:
        table = _processes()
        found = builders(cache, table)
        if found and len(descendants(found, table)) > 1:
            return proc, cache, found[0]
        if proc.poll() is not None and not found:
            break
        time.sleep(0.05)
    return proc, cache, None


def _until_gone(pids, guard: float = 60.0) -> float | None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < guard:
        table = _processes()
        if not [p for p in pids if p in table and table[p][2] not in ("Z", "X")]:
            return time.monotonic() - t0
        time.sleep(0.01)
    return None


def deleted_cache(work: Path) -> dict:
    """Part 2 (module docstring)."""
    proc, cache, builder = _cold_plan_with_builder(work, "deleted")
    if builder is None:
        proc.kill()
        return {"error": "no builder seen"}
    group = descendants([builder], _processes())
    t0 = time.monotonic()
    shutil.rmtree(cache, ignore_errors=True)
    gone = _until_gone(group)
    spent = None if gone is None else time.monotonic() - t0
    _end(proc)
    return {"builder_and_compiler_gone_s": None if spent is None else round(spent, 3),
            "processes": len(group)}


def _end(proc) -> None:
    if proc.poll() is None:
        with_group = proc.pid
        try:
            os.killpg(with_group, signal.SIGKILL)
        except OSError:
            proc.kill()
    proc.wait()


def sighup_plan(work: Path) -> dict:
    """Part 3 (module docstring)."""
    proc, cache, builder = _cold_plan_with_builder(work, "sighup")
    if builder is None:
        _end(proc)
        return {"error": "no builder seen"}
    table = _processes()
    watched = set(descendants([proc.pid, builder], table))
    sent = time.monotonic()
    os.kill(proc.pid, signal.SIGHUP)
    try:
        status = proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        _end(proc)
        status = None
    ended = time.monotonic()
    gone = _until_gone(watched, guard=10.0)
    left_after_2s = None
    if gone is None or gone > 2.0:
        table = _processes()
        left_after_2s = len([p for p in watched if p in table and table[p][2] not in ("Z", "X")])
    else:
        left_after_2s = 0
    shutil.rmtree(cache, ignore_errors=True)
    return {"exit_status": status, "plan_ended_s": round(ended - sent, 3),
            "all_gone_after_plan_ended_s": None if gone is None else round(gone, 3),
            "processes_watched": len(watched), "left_2s_after_the_plan_ended": left_after_2s}


def signal_builder(work: Path, signame: str) -> dict:
    """Part 4 (module docstring): the builder of a cold plan sent ``signame``."""
    proc, cache, builder = _cold_plan_with_builder(work, f"builder-{signame}")
    if builder is None:
        _end(proc)
        return {"error": "no builder seen"}
    group = descendants([builder], _processes())
    os.kill(builder, getattr(signal, signame))
    gone = _until_gone(group)
    _end(proc)
    shutil.rmtree(cache, ignore_errors=True)
    return {"builder_and_compiler_gone_s": None if gone is None else round(gone, 3), "processes": len(group)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plans", type=int, default=20)
    parser.add_argument("--json", default=None)
    parser.add_argument("--drain", type=float, default=1800.0,
                        help="the longest wait for the builder after the last plan (s)")
    parser.add_argument("--skip-signals", action="store_true", help="the session only")
    args = parser.parse_args(argv)
    if not Path("/proc/self/stat").exists() or not (shutil.which("gcc") or shutil.which("cc")):
        print("needs Linux /proc and a C compiler", file=sys.stderr)
        return 2
    report = {"load_before": os.getloadavg()}
    with tempfile.TemporaryDirectory(prefix="bench-builders-") as tmp:
        work = Path(tmp)
        if not args.skip_signals:
            report["sighup_plan"] = sighup_plan(work)
            report["deleted_cache"] = deleted_cache(work)
            report["builder_sigterm"] = signal_builder(work, "SIGTERM")
            report["builder_sighup"] = signal_builder(work, "SIGHUP")
        report["session"] = session(args.plans, work, args.drain)
    report["load_after"] = os.getloadavg()
    s = report["session"]
    print(f"load average {report['load_before'][0]:.1f} → {report['load_after'][0]:.1f}")
    print(f"session: {s['plans']} cold plans on {len(ROBOTS)} robots, one cache: at most "
          f"{s['max_builders_alive']} "
          f"builder process(es) alive in {s['samples']} samples; builds asked {s['builds_asked']}, built "
          f"{s['builds_built']}, dropped as stale or unbuilt {s['builds_dropped_or_unbuilt']}; the builder "
          "left "
          f"{s['builder_after_last_plan_s']} s after the last plan and {s['builder_after_last_library_s']} s "
          f"after its last library landed (compile_s of the builds: {s['compile_s']})")
    if not args.skip_signals:
        print(f"deleted cache: builder and compiler gone in {report['deleted_cache']}")
        print(f"SIGHUP to a cold plan: {report['sighup_plan']}")
        print(f"SIGTERM to a builder: {report['builder_sigterm']}; "
              f"SIGHUP to a builder: {report['builder_sighup']}")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
