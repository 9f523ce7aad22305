"""``nhgait plan`` as a user runs it, cold and then warm, measured from outside (issue 25).

Shared by ``bench_scale.py`` and ``bench_ocp.py``::

    row = cold_and_warm(["snake_6.toml"], folder, cache, timeout=600)
    row["cold_s"], row["warm_s"], row["cold_over_warm"], row["background"]["compile_s"]

* **cold** — the whole ``nhgait plan ARGS --no-gif`` process with an empty private cache
  (``NHGAIT_CACHE_DIR``): start-up, derivation, specialisation, NLP set-up and code (the fast
  compiler's, or interpreted), solves, verification, files. Its wall time, the longest time
  between two progress lines on stderr, the peak resident memory of its process tree (the
  largest single process: nhgait, a solver child or a compiler it waited for) and what
  solution.json says: which code solved, the C size, what was started for later.
* **the background build** — the optimised library the cold plan started
  (:mod:`nhgait.dynamics.numerics.background`) waited for, and its record: the compiler's
  flags, seconds and peak resident memory.
* **warm** — the same command again, the cache now holding the derivation and the optimised
  library; its wall time. ``cold_over_warm`` is the ratio of the two (issue 25's target: ≤ 2).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

#: prints the peak RSS (kB) of every process the command started (RUSAGE_CHILDREN)
_WRAPPER = ("import resource, subprocess, sys; rc = subprocess.call(sys.argv[1:]); "
            "print('PEAK_RSS_KB', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
            "sys.exit(rc)")


def nhgait_command() -> list:
    exe = Path(sys.executable).with_name("nhgait")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "nhgait.gaits.cli.main"]


def run_plan(args: list, out: Path, cache: Path, timeout: float) -> dict:
    """``nhgait plan ARGS --no-gif --out OUT`` in a fresh process with the cache ``cache`` (module
    docstring); a run not finished in ``timeout`` s is killed and says so in ``status``."""
    env = {**os.environ, "NHGAIT_CACHE_DIR": str(cache), "NHGAIT_BACKGROUND_BUILDS": "1"}
    cmd = [sys.executable, "-c", _WRAPPER, *nhgait_command(), "plan", *map(str, args), "--no-gif",
           "--out", str(out)]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stamps, lines, peak = [t0], [], 0
    try:
        for line in proc.stderr:
            stamps.append(time.monotonic())
            lines.append(line.rstrip())
            m = re.match(r"PEAK_RSS_KB (\d+)", line)
            if m:
                peak = int(m.group(1))
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return {"status": f"plan not finished in {timeout:.0f} s"}
    stamps.append(time.monotonic())
    row = {"exit": proc.returncode, "wall_s": stamps[-1] - t0, "peak_mb": peak / 1024.0,
           "max_silent_s": max(b - a for a, b in zip(stamps, stamps[1:], strict=False)),
           "stderr_tail": lines[-5:]}
    path = out / "solution.json"
    if path.exists():
        row.update(_solution_fields(json.loads(path.read_text())))
    return row


def _solution_fields(data: dict) -> dict:
    st = data["settings"]
    comp = st.get("compile") or {}
    verification = data.get("verification") or {}
    return {"success": data["success"], "status": data["status"], "objective": data["objective"],
            "iterations": data["iterations"], "guess": data["guess"]["won"], "solver": st.get("solver"),
            "hessian": st.get("hessian"), "stage": st.get("stage"),
            "coarse": st.get("coarse_intervals") is not None,
            "ode_operations": st.get("ode_operations"),
            "c_bytes": comp.get("c_bytes", 0),
            "code": comp.get("code", "interpreted" if not st.get("jit") else "?"),
            "compiler": comp.get("compiler"), "flags": comp.get("flags"),
            "compile_s": comp.get("compile_s", 0.0),
            "later": comp.get("later"), "verification_error": verification.get("max_error"),
            "condition_error": verification.get("max_condition_error"), "velocities": st.get("velocities"),
            "phases": {k: st[k] for k in st if k.endswith("_s")}}


def background_build(later: dict | None, cache: Path, timeout: float) -> dict:
    """Wait for the optimised build a cold plan started (``later`` from its solution.json) and
    read its record: flags, compile seconds, compiler peak memory, how long it was waited for."""
    from nhgait.dynamics.numerics.background import wait_for_build
    if not later or later.get("state") not in ("started", "queued"):
        return {"state": (later or {}).get("state", "none"), "reason": (later or {}).get("reason", "")}
    jit = Path(cache) / "jit"
    t0 = time.monotonic()
    done = wait_for_build(later["key"], later["pid"], timeout, directory=jit)
    record = jit / f"{later['key']}.json"
    row = {"state": "built" if record.exists() else ("failed" if done else "still running"),
           "waited_s": time.monotonic() - t0, "flags": later.get("flags")}
    if record.exists():
        data = json.loads(record.read_text())
        row.update(compile_s=data.get("compile_s"), peak_mb=data.get("compiler_peak_mb"),
                   c_bytes=data.get("c_bytes"))
    failed = jit / f"{later['key']}.failed"
    if failed.exists():
        row["reason"] = json.loads(failed.read_text()).get("reason")
    return row


def cold_and_warm(args: list, folder: Path, cache: Path, timeout: float) -> dict:
    """The cold run, its background build, the warm run (module docstring): the cold run's
    fields (``cold_s`` its wall time), ``background``, ``warm_s``, ``warm`` (the warm run's
    code, exit and peak) and ``cold_over_warm``."""
    cold = run_plan(args, folder / "cold_out", cache, timeout)
    if "wall_s" not in cold:
        return cold
    row = {**cold, "cold_s": cold.pop("wall_s")}
    row["background"] = background_build(cold.get("later"), cache, timeout)
    warm = run_plan(args, folder / "warm_out", cache, timeout)
    if "wall_s" in warm:
        row.update(warm_s=warm["wall_s"], cold_over_warm=row["cold_s"] / warm["wall_s"],
                   warm={k: warm.get(k) for k in ("exit", "success", "code", "flags", "peak_mb", "objective",
                                                  "iterations", "phases")})
    return row
