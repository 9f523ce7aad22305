"""The candidates' order is made lazily (gaits/planning/guesses.py: ``RankedOrder``): the shape
loops are ranked only when a candidate past the leading ones is asked for, and the ranking
reorders without losing or repeating a candidate."""
from __future__ import annotations

import pytest

from nhgait.gaits.planning.guesses import RankedOrder


def test_the_tail_is_made_only_when_an_item_past_the_head_is_asked_for():
    made = []

    def tail():
        made.append(1)
        return ["b", "c", "d"]

    order = RankedOrder(["path"], tail, 3)
    assert len(order) == 4 and order[0] == "path" and made == []      # the head alone: no ranking
    assert order[1] == "b" and made == [1]
    assert order[-1] == "d" and order[1:3] == ["b", "c"] and made == [1]   # made once
    with pytest.raises(IndexError):
        order[4]


def test_candidates_rank_the_snakeboards_loops_without_losing_one():
    """The snakeboard forward (a scene of the user robots): every generated guess is handed out
    exactly once, the loops predicted to move away from x = +0.6 after the rest."""
    from pathlib import Path

    from nhgait.gaits.planner import prepare
    from nhgait.gaits.planning import guesses
    from nhgait.gaits.planning.loop_ranking import loop_scores
    from nhgait.gaits.tasks.sources import resolve
    scene = Path(__file__).resolve().parents[2] / "experiments" / "user_robots" / "snakeboard_fwd.toml"
    problem = prepare(resolve(str(scene))).problem
    generated = guesses._order(guesses.shape_guesses(problem, tuple(problem.model.shape), ()), 1)
    order = guesses.candidates(problem, screen=False)._shapes
    labels = [order[i].label for i in range(len(order))]
    rollouts = guesses.rollout_guesses(problem, tuple(problem.model.shape),
                                       guesses._rate_states(problem.model, tuple(problem.model.shape)))
    assert sorted(g.label for g in generated) == sorted(label for label in labels
                                                        if label not in {g.label for g in rollouts}
                                                        and label != "fitted roll-out")
    scores = {s.label: s for s in loop_scores(problem, generated) if s is not None}
    away = [label for label in labels if label in scores and scores[label].score < 0]
    toward = [label for label in labels if label in scores and scores[label].score > 0]
    assert away and toward
    assert max(labels.index(a) for a in toward) < min(labels.index(a) for a in away)
    assert labels[-1] == "ramps only"                                # the last resort stays last
    assert min(labels.index(a) for a in away) > max(i for i, label in enumerate(labels)
                                                    if label not in away and label != "ramps only")
