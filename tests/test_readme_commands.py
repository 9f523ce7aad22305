"""Every command in README.md runs as written (issue 43: a README of one screen whose commands
work). The fenced ``sh`` blocks are read from the README itself, so a command edited there is
the command tested: ``nhgait …`` lines run in a shell in a temporary folder (``out/…`` goes
there; ``examples/`` is the repository's, linked in), with this environment's ``nhgait`` first
on PATH; ``make …`` lines are checked with ``make -n`` (the target exists and its recipe
expands: ``make test`` cannot run inside the test suite, ``make demo`` would install a second
environment); the ``python`` blocks run in a fresh interpreter. Each command's outputs are
checked against what the README says it writes.
"""
from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _blocks(language: str) -> list:
    return re.findall(rf"```{language}\n(.*?)```", README.read_text(), re.S)


def _commands() -> list:
    """The command lines of the sh blocks (comments removed, continuation lines joined)."""
    lines = []
    for block in _blocks("sh"):
        for line in block.replace("\\\n", " ").splitlines():
            command = line.split(" #")[0].strip()
            if command and not command.startswith("#"):
                lines.append(command)
    return lines


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("readme")
    (folder / "examples").symlink_to(ROOT / "examples")
    return folder


def _env() -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env.setdefault("MPLBACKEND", "Agg")
    return env


def test_the_readme_is_one_screen_with_three_commands():
    text = README.read_text()
    assert len(text.splitlines()) <= 120
    nhgait = [c for c in _commands() if c.startswith("nhgait ")]
    assert len(nhgait) == 3, nhgait
    assert [c.split()[0] for c in _commands()].count("make") == 2


def test_make_targets_of_the_readme_exist():
    for command in _commands():
        if command.startswith("make "):
            args = shlex.split(command)
            done = subprocess.run(["make", "-n", *args[1:]], cwd=ROOT, capture_output=True, text=True,
                                  env=_env(), timeout=60)
            assert done.returncode == 0, (command, done.stderr)
            assert done.stdout.strip(), command


def test_every_nhgait_command_of_the_readme_runs_as_written(workdir):
    commands = [c for c in _commands() if c.startswith("nhgait ")]
    for command in commands:
        done = subprocess.run(["bash", "-c", command], cwd=workdir, capture_output=True, text=True,
                              env=_env(), timeout=300)
        assert done.returncode == 0, (command, done.stdout[-2000:], done.stderr[-2000:])
        out = shlex.split(command)
        if "--plot" in out:                       # simulate: the three figures the README names
            folder = workdir / out[out.index("--plot") + 1]
            for name in ("time_series.png", "path.png", "checks.png"):
                assert (folder / name).stat().st_size > 1000, (command, name)
        if "--out" in out:                        # plan: a verified gait and its figures
            folder = workdir / out[out.index("--out") + 1]
            data = json.loads((folder / "solution.json").read_text())
            assert data["success"] and data["verification"]["passed"], command
            assert (folder / "path.png").stat().st_size > 1000
            if "--gif" in out:
                assert (folder / "motion.gif").stat().st_size > 1000
            if "--set" in out:                    # the override reached the task: y(T) = 0.8
                key, value = out[out.index("--set") + 1].split("=")
                assert key == "final.y"
                assert data["trajectory"]["q"][-1][1] == pytest.approx(float(value), abs=1e-6)


def test_the_python_blocks_of_the_readme_run_as_written(workdir):
    for code in _blocks("python"):
        done = subprocess.run([sys.executable, "-c", code], cwd=workdir, capture_output=True, text=True,
                              env=_env(), timeout=300)
        assert done.returncode == 0, (code, done.stderr[-2000:])
        assert "SUCCESS" in done.stdout, done.stdout
