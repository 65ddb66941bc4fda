"""Harder training layouts (``MAPPOConfig.hard_layouts``)."""
import pytest
import torch

from masp_lite.algos.curriculum import LANDMARK_NEAR, OBSTACLE_NEAR, harden_layouts
from masp_lite.envs import make


def _near(world):
    lm, ob = world.landmark_pos, world.obstacle_pos
    d = torch.cdist(lm, lm) + torch.eye(world.num_agents) * 99
    return (d.min(-1).values < LANDMARK_NEAR) | (torch.cdist(lm, ob).min(-1).values < OBSTACLE_NEAR)


def test_moved_landmarks_sit_near_a_landmark_or_an_obstacle_and_keep_the_spawn_rules():
    w = make("mpe-5", num_envs=400, seed=0)
    before = {k: getattr(w, k).clone() for k in ("agent_pos", "obstacle_pos", "landmark_pos")}
    ids = harden_layouts(w, 0.5, torch.Generator().manual_seed(0))
    moved = (w.landmark_pos != before["landmark_pos"]).any(-1)                # (B, N)
    assert 150 < len(ids) < 250 and moved.sum(1).max() == 1
    assert sorted(torch.nonzero(moved.any(1)).flatten().tolist()) == sorted(ids.tolist())
    assert bool(_near(w)[moved].all())
    assert torch.equal(w.agent_pos, before["agent_pos"]) and torch.equal(w.obstacle_pos, before["obstacle_pos"])
    sc = w.scenario
    lm, ob = w.landmark_pos, w.obstacle_pos
    assert bool((lm.abs() <= sc.world_size / 2 - sc.landmark_radius).all())
    assert bool((torch.cdist(lm, ob) >= sc.landmark_radius + sc.obstacle_radius).all())
    d = torch.cdist(lm, lm) + torch.eye(5) * 99
    assert bool((d >= 2 * sc.landmark_radius).all())
    assert bool((w.t == 0).all()) and torch.equal(w.reached, w.covered)


def test_same_generator_same_layouts_and_the_worlds_stream_is_untouched():
    a, b, c = (make("mpe-5", num_envs=50, seed=4) for _ in range(3))
    harden_layouts(a, 1.0, torch.Generator().manual_seed(7))
    harden_layouts(b, 1.0, torch.Generator().manual_seed(7))
    assert torch.equal(a.landmark_pos, b.landmark_pos)
    assert harden_layouts(c, 0.0, torch.Generator().manual_seed(7)).numel() == 0
    a.reset(), c.reset()                                   # the next spawns come from the world's own stream
    assert torch.equal(a.landmark_pos, c.landmark_pos)


def test_a_shrinking_team_keeps_who_stays():
    w = make("mpe-20to10", num_envs=20, seed=1)
    keep = w._keep.clone()
    harden_layouts(w, 1.0, torch.Generator().manual_seed(0))
    assert torch.equal(w._keep, keep)
    with pytest.raises(ValueError, match="fraction"):
        harden_layouts(w, 2.0, torch.Generator())


def test_training_collects_on_the_hardened_layouts():
    from masp_lite.algos.mappo import MAPPOConfig
    from masp_lite.algos.masp_trainer import MASPTrainer
    plain = MASPTrainer("mpe-5", MAPPOConfig(num_envs=6, width=8), seed=0)
    hard = MASPTrainer("mpe-5", MAPPOConfig(num_envs=6, width=8, hard_layouts=1.0), seed=0)
    (_, a, _), (_, b, _) = plain.collect(), hard.collect()
    moved = (a["landmark_pos"][0] != b["landmark_pos"][0]).any(-1)           # (B, N) at t = 0
    assert bool((moved.sum(1) == 1).all())
    assert torch.equal(a["obstacle_pos"], b["obstacle_pos"])
