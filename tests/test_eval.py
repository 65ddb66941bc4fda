"""Metrics on hand-built episodes, rollout timing/determinism, evaluate records, tables."""
import json

import numpy as np
import pytest
import torch

from masp_lite.envs import make
from masp_lite.evaluation import (
    CONTACT_KINDS,
    EpisodeLog,
    collision_rate,
    contact_breakdown,
    evaluate,
    format_table,
    rollout,
    steps,
    success_rate,
)
from masp_lite.parsing import parse_value
from masp_lite.policies.reference import RandomPolicy


def log_of(covered, reached=None, collisions=None, varying=False, horizon=None):
    """An EpisodeLog from a (E, T+1, L) list/array of coverage; alive all true."""
    cov = torch.as_tensor(np.asarray(covered, dtype=bool))
    E, T1, L = cov.shape
    rea = cov.cummax(dim=1).values if reached is None else torch.as_tensor(np.asarray(reached, dtype=bool))
    col = torch.zeros(E, T1 - 1, dtype=torch.long) if collisions is None else torch.as_tensor(collisions)
    return EpisodeLog(cov, rea, col, torch.ones(E, T1, 3, dtype=torch.bool), varying=varying,
                      horizon=T1 - 1 if horizon is None else horizon)


def test_steps_first_step_all_covered():
    T, L = 10, 3
    cov = np.zeros((3, T + 1, L), dtype=bool)
    cov[0, 7:] = True            # all covered from t = 7 on -> Steps 7, SR 1
    cov[1, :, :2] = True         # one landmark never covered -> horizon, SR 2/3
    cov[2, 4, :] = True          # all covered only at t = 4, lost afterwards -> Steps 4, SR 0
    cov[2, 5:, 0] = True
    log = log_of(cov)
    assert steps(log).tolist() == [7.0, 10.0, 4.0]
    assert success_rate(log).tolist() == pytest.approx([1.0, 2 / 3, 1 / 3])


def test_steps_zero_when_solved_at_spawn_and_not_simultaneous():
    cov = np.ones((1, 5, 2), dtype=bool)
    assert steps(log_of(cov)).tolist() == [0.0]
    # fixed team: landmarks covered at different times, never together -> horizon
    cov = np.zeros((1, 5, 2), dtype=bool)
    cov[0, 1, 0] = cov[0, 3, 1] = True
    assert steps(log_of(cov)).tolist() == [4.0]
    # the same episode under the varying-team rule counts "ever reached": done at t = 3
    assert steps(log_of(cov, varying=True)).tolist() == [3.0]
    assert success_rate(log_of(cov, varying=True)).tolist() == [1.0]
    assert success_rate(log_of(cov)).tolist() == [0.0]


def test_collision_rate_counts_events_per_step():
    cov = np.zeros((2, 5, 2), dtype=bool)
    col = torch.tensor([[0, 2, 1, 0], [0, 0, 0, 0]])
    assert collision_rate(log_of(cov, collisions=col)).tolist() == [0.75, 0.0]


def test_log_validates_shapes():
    with pytest.raises(ValueError, match="collisions"):
        EpisodeLog(torch.zeros(1, 3, 2, dtype=torch.bool), torch.zeros(1, 3, 2, dtype=torch.bool),
                   torch.zeros(1, 3, dtype=torch.long), torch.ones(1, 3, 2, dtype=torch.bool),
                   varying=False, horizon=2)


def test_rollout_matches_world_and_is_deterministic():
    world = make("mpe-5", num_envs=4, seed=0, horizon=6)
    log, dt = rollout(world, RandomPolicy(world, seed=1), episodes=6, seed=2)
    assert log.covered.shape == (6, 7, 5) and log.collisions.shape == (6, 6) and dt > 0
    world2 = make("mpe-5", num_envs=4, seed=9, horizon=6)
    log2, _ = rollout(world2, RandomPolicy(world2, seed=1), episodes=6, seed=2)
    assert torch.equal(log.covered, log2.covered) and torch.equal(log.collisions, log2.collisions)
    # the log replays the world: the last batch's final coverage is the world's
    assert torch.equal(log.covered[4:, -1], world.covered[:2])


def test_contact_breakdown_adds_up_to_cr_on_the_same_episodes():
    # a crowded map, so that every kind of contact happens; 6 episodes in batches of 4
    kw = dict(num_envs=4, seed=0, horizon=12, num_agents=8, num_obstacles=8, world_size=2.2)
    w1, w2 = make("mpe-5", **kw), make("mpe-5", **kw)
    log, _ = rollout(w1, RandomPolicy(w1, seed=1), episodes=6, seed=2)
    parts = contact_breakdown(w2, RandomPolicy(w2, seed=1), episodes=6, seed=2)
    assert set(parts) == {*CONTACT_KINDS, "total"}
    assert parts["total"] == pytest.approx(float(collision_rate(log).mean()), abs=1e-12)
    assert sum(parts[k] for k in CONTACT_KINDS) == pytest.approx(parts["total"])
    assert parts[CONTACT_KINDS[1]] > 0 and parts[CONTACT_KINDS[3]] > 0, parts  # contacts did happen
    with pytest.raises(ValueError, match="particle"):
        contact_breakdown(make("drone-5", num_envs=1), RandomPolicy(w1), episodes=1)


def test_contact_breakdown_on_landmark_or_en_route():
    w = make("mpe-5", num_envs=1, seed=0, num_agents=3, num_obstacles=1, horizon=1)

    class Still:
        def reset(self, obs):
            pass

        def act(self, obs):
            return torch.zeros(1, 3, dtype=torch.long)

    # after one step agents 0 and 1 touch, both on their landmarks; agent 2 touches the obstacle
    # away from any landmark (they start 0.21 m apart and drift 0.01-0.02 m closer)
    w.reset = lambda seed=None, _r=w.reset: _r(options={
        "agent_pos": [[0.0, 0.0], [0.21, 0.0], [-0.8, -0.8]], "landmark_pos": [[0.0, 0.05], [0.21, 0.05], [0.8, 0.8]],
        "obstacle_pos": [[-0.8, -0.59]], "agent_vel": [[0.1, 0.0], [-0.1, 0.0], [0.0, 0.2]]})
    parts = contact_breakdown(w, Still(), episodes=1)
    assert parts == {CONTACT_KINDS[0]: 1.0, CONTACT_KINDS[1]: 0.0, CONTACT_KINDS[2]: 0.0, CONTACT_KINDS[3]: 1.0,
                     "total": 2.0}


def test_evaluate_record_and_table():
    rec = evaluate("random", "mpe-5", episodes=3, seeds=(0, 1), overrides={"horizon": 4})
    assert set(rec) >= {"method", "scenario", "seeds", "episodes_per_seed", "sr", "steps", "cr",
                        "decision_ms"}
    assert rec["seeds"] == [0, 1] and rec["episodes_per_seed"] == 3
    assert rec["threads"] == torch.get_num_threads()  # a float sum's rounding depends on it (test_records)
    json.dumps(rec)  # serialisable
    assert rec["steps"] == {"mean": None, "std": None}  # random never covers all in 4 steps
    text = format_table([rec])
    assert "\\" in text.splitlines()[-1] and "random" in text
    assert r"$\backslash$" in format_table(rec, fmt="latex")


def test_table_format_two_decimals():
    rec = {"method": "m", "scenario": "mpe-5", "steps": {"mean": 7.544, "std": 1.371},
           "sr": {"mean": 1.0, "std": 0.0}, "cr": {"mean": 0.47, "std": 0.012},
           "decision_ms": {"mean": 14.0, "std": 0.5}}
    row = format_table([rec], fmt="text").splitlines()[1]
    assert "7.54 (1.37)" in row and "1.00 (0.00)" in row and "0.47 (0.01)" in row
    assert "7.54\\scriptsize{(1.37)}" in format_table([rec], fmt="latex")
    with pytest.raises(ValueError, match="fmt"):
        format_table([rec], fmt="html")


def test_paper_layout_has_metric_rows_and_method_columns():
    def rec(method, scenario, steps):
        return {"method": method, "scenario": scenario, "steps": {"mean": steps, "std": 1.0 if steps else None},
                "sr": {"mean": 0.5, "std": 0.1}, "cr": {"mean": 0.25, "std": 0.0},
                "decision_ms": {"mean": 1.0, "std": 0.0}}
    rows = [rec("a", "mpe-5", 9.0), rec("b", "mpe-5", None), rec("a", "mpe-20", 30.0)]
    lines = format_table(rows, fmt="text", layout="paper").splitlines()
    assert lines[0].split() == ["Scenario", "Metric", "a", "b"] and len(lines) == 1 + 3 * 2
    assert lines[1].split() == ["mpe-5", "Steps", "↓", "9.00", "(1.00)", "\\"]
    assert lines[4].split()[:2] == ["mpe-20", "Steps"]
    latex = format_table(rows, fmt="latex", layout="paper")
    assert r"\textit{SR} $\uparrow$ & 0.50\scriptsize{(0.10)} & 0.50\scriptsize{(0.10)} \\" in latex


def test_parse_value():
    assert [parse_value(x) for x in ("3", "0.5", "True", "none", "abc")] == [3, 0.5, True, None, "abc"]
    assert parse_value("none", int | None) is None and parse_value("4", int | None) == 4
    assert parse_value("2", float) == 2.0 and parse_value("1, 2", tuple[int, ...]) == (1, 2)
    for text, typ in (("x", int), ("2.5", int), ("yes", bool), ("none", int)):
        with pytest.raises(ValueError, match="expected"):
            parse_value(text, typ)


def test_evaluate_bad_input():
    with pytest.raises(ValueError, match="h-greedy"):
        evaluate("nope", "mpe-5", episodes=1)
    with pytest.raises(ValueError, match="unknown option"):
        evaluate("random", "mpe-5", episodes=1, method_options={"speed": 2})
    with pytest.raises(ValueError, match="seeds"):
        evaluate("random", "mpe-5", episodes=1, seeds=[])
    with pytest.raises(ValueError, match="seeds"):
        evaluate("random", "mpe-5", episodes=1, seeds=0)
    with pytest.raises(ValueError, match="checkpoint"):
        evaluate("random", "mpe-5", episodes=1, checkpoint="x.pt")


# ------------------------------------------------------------------ claims
def test_better_and_verdict_metric_by_metric():
    from masp_lite.reproduction.claims import better, verdict
    assert better("sr", 0.9, 0.8) == "a" and better("steps", 9.0, 8.0) == "b" and better("cr", 0.1, 0.2) == "a"
    assert better("steps", None, 40.0) == "b" and better("steps", 40.0, None) == "a"
    assert better("steps", None, None) == "neither" and better("cr", 0.3, 0.3 + 1e-12) == "tie"
    with pytest.raises(ValueError, match="metric"):
        better("speed", 1.0, 2.0)
    rec = lambda sr, st, cr: {"sr": {"mean": sr, "std": 0.0}, "steps": {"mean": st, "std": None}, "cr": {"mean": cr}}  # noqa: E731
    lines = verdict(rec(0.99, 30.0, 0.2), rec(1.0, None, 0.4), "A", "B")
    assert len(lines) == 3 and lines[0].startswith("SR   : A   0.990   B   1.000") and lines[0].endswith("-> B better")
    assert "B   never" in lines[1] and lines[1].endswith("-> A better") and lines[2].endswith("-> A better")
    assert verdict({"sr": 0.5}, {"sr": 0.5}, metrics=["sr"]) == ["SR   : MASP   0.500   h-greedy   0.500   -> a tie"]


def test_against_paper_uses_the_metrics_the_paper_reports():
    from masp_lite.reproduction.claims import PAPER_MASP, against_paper
    rec = {"scenario": "mpe-50", "sr": {"mean": 1.0}, "steps": {"mean": 50.0}, "cr": {"mean": 0.23}}
    lines = against_paper(rec)
    assert [line.split(":")[0].strip() for line in lines] == ["SR", "Steps", "CR"]
    assert lines[0].endswith("-> ours better") and lines[1].endswith("-> paper better") and lines[2].endswith("a tie")
    assert "paper  47.460" in lines[1] and PAPER_MASP["mpe-50"]["steps"] == 47.46
    varying = against_paper({"scenario": "mpe-20to10", "sr": {"mean": 1.0}, "steps": {"mean": 20.0}, "cr": {"mean": 0}})
    assert len(varying) == 3 and varying[1].startswith("Steps") and varying[1].endswith("-> ours better")
    assert PAPER_MASP["mpe-20to10"] == {"steps": 22.38, "sr": 1.00, "cr": 0.16}   # the paper's varying-team table
    assert against_paper({"scenario": "drone-5", "sr": {"mean": 1.0}}) == []
