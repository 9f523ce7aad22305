#!/usr/bin/env python3
"""SIGTERM at random moments of a plan: does every one end within 2 s, cleanly? (issue 24)

For one member of ``experiments/scale_tasks.py`` (default ``cart_trailers_4``: 8 coordinates,
a cold plan that derives, compiles, solves and verifies in about 15 s), two kinds of run:

* **cold** — ``nhgait plan <scene> --no-gif`` with an empty cache of its own (derivation,
  compilation, guesses, solves, verification, files);
* **warm** — the same with a cache filled beforehand (mostly solves and verification).

Each kind is first run once to the end (its duration T); then ``--trials`` runs (default 30)
each get SIGTERM at a moment drawn uniformly from [0, T] (seeded: ``--seed``). Every run starts
in a session of its own with a private ``TMPDIR``. For each it records:

* the **stop time** — from the signal to the process's exit — and the exit status: 143, or
  death by SIGTERM itself (status −15: the signal came before nhgait installed its handler, in
  the interpreter's start-up, or after it had put the default back, in its teardown once the
  plan was done) — both are what a shell reports as 143;
* the **phase hit** — the innermost phase the progress output says was stopped (``…: stopped
  after``), else the last thing it said;
* **what is left** — live processes of its session half a second after its exit (a process
  sent SIGKILL vanishes when the kernel next schedules it), temporary files anywhere it
  writes (``.tmp-*`` in the cache, ``jit/.build-*`` still there 20 s later — a background
  build's folder, which its detached builder finishes or removes —, ``.writing-*`` in the output folder,
  ``nhgait-jit-*`` and anything else in its ``TMPDIR`` — gcc's own ``cc*.s``/``cc*.o`` among
  them, reported apart: where the compiler's temporaries go is issue 29's), half-written
  outputs (a ``solution.json`` that does not parse).

A run passes when it exits 143 within 2 s and leaves nothing (gcc's temporaries aside). Prints
the distribution of stop times (median, 90th percentile, max), the phases hit and every
failure; writes ``out/stress_sigterm.json``.

Usage: python experiments/stress_sigterm.py [--member cart_trailers_4] [--trials 30] [--seed 24]
       [--kinds cold,warm] [--out out]
"""
from __future__ import annotations

import argparse
import json
import os
import random
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import sibling  # experiments/sibling.py: the other scripts, loaded by file path

#: a run must end this soon after SIGTERM (seconds)
STOP_S = 2.0
#: after the exit, how long a killed process of the session may take to vanish (a process sent
#: SIGKILL dies when the kernel next schedules it: milliseconds, more on a loaded machine)
VANISH_S = 0.5
#: the compiler's own temporaries (gcc -save-temps off: cc*.s, cc*.o, cc*.res, cc*.ld)
GCC_TEMPORARY = re.compile(r"^cc\w+\.(s|o|res|ld|c|i)$")


def _nhgait() -> list:
    exe = Path(sys.executable).with_name("nhgait")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "nhgait.gaits.cli.main"]


def _session_alive(session: int) -> list:
    """Live processes (not zombies) of ``session``: (pid, name)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            head, tail = (entry / "stat").read_text().rsplit(")", 1)
        except OSError:
            continue
        fields = tail.split()
        if fields[0] not in ("Z", "X") and int(fields[3]) == session:
            found.append((int(entry.name), head.split("(", 1)[1]))
    return found


def _run(scene: Path, work: Path, cache: Path, delay: float | None) -> dict:
    """One plan; SIGTERM after ``delay`` seconds (None: to the end)."""
    out, tmp = work / "out", work / "tmp"
    tmp.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "NHGAIT_CACHE_DIR": str(cache), "TMPDIR": str(tmp)}
    err_path = work / "stderr.txt"
    with open(err_path, "w") as err:
        started = time.monotonic()
        proc = subprocess.Popen([*_nhgait(), "plan", str(scene), "--no-gif", "--out", str(out)], env=env,
                                stdout=subprocess.DEVNULL, stderr=err, start_new_session=True)
        status, sent = None, None
        if delay is not None:
            try:
                status = proc.wait(timeout=delay)           # ended before the moment came
            except subprocess.TimeoutExpired:
                sent = time.monotonic()
                proc.send_signal(signal.SIGTERM)
        try:
            status = proc.wait(timeout=120.0 if sent is not None else 1800.0)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            status = proc.wait()
        ended = time.monotonic()
    deadline = time.monotonic() + VANISH_S
    while _session_alive(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.01)
    left = _session_alive(proc.pid)
    for pid, _ in left:                                     # nothing of ours outlives the trial
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    stderr = err_path.read_text()
    said = [line for line in stderr.splitlines() if line.startswith("nhgait:")]
    return {"delay": delay, "signalled": sent is not None, "status": status, "said": said[-1] if said else "",
            "stderr_tail": stderr.splitlines()[-12:] if status not in (143, -signal.SIGTERM) else [],
            "stop_s": (ended - sent) if sent is not None else None, "wall_s": ended - started,
            "phase": _phase(stderr, status), "processes_left": left, **_leftovers(cache, out, tmp)}


def _phase(stderr: str, status) -> str:
    """The innermost phase stopped (the first ``…: stopped after`` line), else where it was."""
    lines = [line for line in stderr.splitlines() if line.startswith("[")]
    if status == -signal.SIGTERM:
        return "teardown (the plan done)" if "nhgait plan" in stderr or lines else "start-up (importing)"
    for line in lines:
        m = re.match(r"\[\s*[\d.]+ s\]\s+(.*?): stopped after", line)
        if m:
            return re.sub(r"\s*\(.*", "", m.group(1)).strip()
    if not lines:
        return "start-up (before the first line)"
    last = re.sub(r"^\[\s*[\d.]+ s\]\s+", "", lines[-1])
    return "between phases, after: " + re.sub(r"[\d.]+", "#", last)[:50]


#: how long a background build's folder may outlive the plan: its builder is detached, finishes
#: into the cache after a plan that ended, and removes the folder itself when the plan stopped
BUILD_GRACE_S = 20.0


def _builds_left(cache: Path) -> list:
    """The ``jit/.build-*`` folders still there :data:`BUILD_GRACE_S` after the plan ended."""
    deadline = time.monotonic() + BUILD_GRACE_S
    while list(cache.glob("jit/.build-*")) and time.monotonic() < deadline:
        time.sleep(0.1)
    return [str(p) for p in cache.glob("jit/.build-*")]


def _leftovers(cache: Path, out: Path, tmp: Path) -> dict:
    temporary = [str(p) for p in cache.glob(".tmp-*")] + _builds_left(cache)
    temporary += [str(p) for p in out.glob(".writing-*")] if out.exists() else []
    in_tmp = [p.name for p in tmp.iterdir()] if tmp.exists() else []
    gcc = [name for name in in_tmp if GCC_TEMPORARY.match(name)]
    temporary += [str(tmp / name) for name in in_tmp if name not in gcc]
    half = []
    solution = out / "solution.json"
    if solution.exists():
        try:
            json.loads(solution.read_text())
        except ValueError:
            half.append(str(solution))
    return {"temporary_left": temporary, "gcc_temporaries_left": gcc, "half_written": half,
            "outputs": sorted(p.name for p in out.iterdir()) if out.exists() else []}


def _passed(row: dict) -> bool:
    if not row["signalled"]:
        return row["status"] in (0, 1) and not row["processes_left"] and not row["temporary_left"]
    return (row["status"] in (143, -signal.SIGTERM) and row["stop_s"] < STOP_S and not row["processes_left"]
            and not row["temporary_left"] and not row["half_written"])


def trials(kind: str, scene: Path, folder: Path, n: int, rng: random.Random, print_=print) -> dict:
    """The full run of ``kind`` (cold/warm) and ``n`` runs signalled at random moments."""
    shared = folder / f"{kind}_cache"
    if kind == "warm":
        _run(scene, folder / "warm_fill", shared, None)             # fill the cache once
    full = _run(scene, folder / f"{kind}_full", folder / "full_cache" if kind == "cold" else shared, None)
    print_(f"{kind}: a full run takes {full['wall_s']:.1f} s (exit {full['status']})")
    rows = []
    for i in range(n):
        delay = rng.uniform(0.0, full["wall_s"])
        cache = folder / f"{kind}_{i}_cache" if kind == "cold" else shared
        row = _run(scene, folder / f"{kind}_{i}", cache, delay)
        row["passed"] = _passed(row)
        rows.append(row)
        stop = f"{row['stop_s']:.2f} s" if row["stop_s"] is not None else "ended before"
        print_(f"  {kind} {i + 1:2d}/{n}: SIGTERM at {delay:5.1f} s → exit {row['status']} after {stop} "
               f"[{row['phase']}]{'' if row['passed'] else '  FAILED: ' + _why(row)}")
        if kind == "cold":
            shutil.rmtree(cache, ignore_errors=True)
    return {"full": full, "trials": rows}


def _why(row: dict) -> str:
    reasons = []
    if row["status"] not in (143, -signal.SIGTERM):
        reasons.append(f"exit {row['status']} ({row['said']})")
    if row["stop_s"] is not None and row["stop_s"] >= STOP_S:
        reasons.append(f"stopped after {row['stop_s']:.2f} s")
    for key in ("processes_left", "temporary_left", "half_written"):
        if row[key]:
            reasons.append(f"{key}: {row[key]}")
    return "; ".join(reasons)


def summary(results: dict) -> list:
    lines = []
    for kind, result in results.items():
        hit = [r for r in result["trials"] if r["signalled"]]
        stops = sorted(r["stop_s"] for r in hit)
        if not stops:
            continue
        p90 = stops[min(len(stops) - 1, int(round(0.9 * (len(stops) - 1))))]
        lines.append(f"{kind}: {len(hit)} runs signalled ({len(result['trials']) - len(hit)} ended "
                     "first); stop time "
                     f"median {statistics.median(stops):.3f} s, 90th percentile {p90:.3f} s, max "
                     f"{stops[-1]:.3f} s; "
                     f"{sum(r['passed'] for r in result['trials'])}/{len(result['trials'])} passed")
        phases = Counter(r["phase"] for r in hit)
        lines.append("  phases hit: " + ", ".join(f"{name} ×{count}" for name, count in phases.most_common()))
        gcc = sum(bool(r["gcc_temporaries_left"]) for r in hit)
        if gcc:
            lines.append(f"  gcc's own temporaries left in TMPDIR by {gcc} runs stopped while compiling "
                         "(where the compiler's temporaries go: issue 29)")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--member", default="cart_trailers_4")
    parser.add_argument("--trials", type=int, default=30)
    parser.add_argument("--seed", type=int, default=24)
    parser.add_argument("--kinds", default="cold,warm")
    parser.add_argument("--out", default="out")
    args = parser.parse_args(argv)
    rng = random.Random(args.seed)
    results = {}
    with tempfile.TemporaryDirectory(prefix="stress-sigterm-") as tmp:
        folder = Path(tmp)
        scene = folder / f"{args.member}.toml"
        scene.write_text(sibling.load("scale_tasks").scene_with_task(args.member))
        for kind in args.kinds.split(","):
            results[kind] = trials(kind, scene, folder, args.trials, rng)
    for line in summary(results):
        print(line)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "stress_sigterm.json").write_text(json.dumps({"member": args.member, "seed": args.seed,
                                                         "stop_bound_s": STOP_S,
                                                         "results": results}, indent=1))
    return 0 if all(r["passed"] for result in results.values() for r in result["trials"]) else 1


if __name__ == "__main__":
    sys.exit(main())
