"""examples/rockit_gait.py (issue 43): the snakeboard's forward gait planned in rockit on
nhgait's model reaches nhgait's J for the same task to 1e-4 relative. rockit transcribes and
Ipopt solves its own NLP (its own multiple shooting, integral and constraints) from a guess of
its own; only the model is nhgait's. Skipped when rockit (pip package rockit-meco) is absent."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

pytest.importorskip("rockit")

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rockit_gait.py"


def _example():
    spec = importlib.util.spec_from_file_location("rockit_gait", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_rockit_reaches_nhgaits_objective():
    example = _example()
    J_rockit, solution = example.rockit_plan(example.nhgait_model())
    J_nhgait = example.nhgait_plan()
    assert abs(J_rockit - J_nhgait) <= 1e-4 * abs(J_nhgait), (J_rockit, J_nhgait)
    assert 0.05 < J_nhgait < 0.2            # the thesis' P2 costs about 0.11 (N·m)²·s
