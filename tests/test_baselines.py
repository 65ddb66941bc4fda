"""The goal-based RL baselines: their executors' views, their trainer settings, their weights' checks."""
import pytest
import torch

from masp_lite.__main__ import main
from masp_lite.algos.masp_trainer import MASPTrainer
from masp_lite.algos.team import hungarian_goals
from masp_lite.config import NetConfig
from masp_lite.envs import make
from masp_lite.nets.baselines import AttentionSubgraph, NearestMLP, nearest_others
from masp_lite.nets.features import pair_features
from masp_lite.nets.masp import MASPNets
from masp_lite.policies import make_policy
from masp_lite.training import method_config
from masp_lite.weights import save_weights


def test_nearest_others_skips_self_and_dropped_agents_and_pads():
    pos = torch.tensor([[[0.0, 0.0], [0.3, 0.0], [0.1, 0.0], [0.2, 0.0]]])
    pair = pair_features(pos, torch.zeros_like(pos))
    alive = torch.tensor([[True, True, True, False]])
    idx, ok = nearest_others(pair, alive, 4)
    assert idx[0, 0, :2].tolist() == [2, 1] and ok[0, 0].tolist() == [True, True, False, False]
    assert idx[0, 1, :2].tolist() == [2, 0]                       # agent 3 is dropped: never seen
    idx, ok = nearest_others(pair[:, :1, :1], alive[:, :1], 3)    # a lone agent sees nobody
    assert not ok.any()


@pytest.mark.parametrize("cls", [NearestMLP, AttentionSubgraph])
def test_baseline_views_serve_any_team_size_and_ignore_dropped_agents(cls):
    torch.manual_seed(0)
    net = cls(6, 8, neighbours=3)
    for n in (1, 2, 5, 20):
        pos, vel = torch.rand(2, n, 2), torch.randn(2, n, 2)
        assert net(pair_features(pos, vel), None, torch.ones(2, n, dtype=torch.bool)).shape == (2, n, 8)
    pos, vel = torch.rand(1, 6, 2), torch.randn(1, 6, 2)
    alive = torch.tensor([[True, True, False, True, True, True]])
    out = net(pair_features(pos, vel), None, alive)
    moved = pos.clone()
    moved[0, 2] = pos[0, 0]                                        # a dropped agent moves onto agent 0
    again = net(pair_features(moved, vel), None, alive)
    torch.testing.assert_close(again[0, alive[0]], out[0, alive[0]])


def test_attention_subgraph_selects_the_best_scored_and_trains_the_scores():
    torch.manual_seed(1)
    net = AttentionSubgraph(6, 8, neighbours=2)
    pos, vel = torch.rand(1, 5, 2), torch.randn(1, 5, 2)
    pair, alive = pair_features(pos, vel), torch.ones(1, 5, dtype=torch.bool)
    scores = net.score(pair).squeeze(-1).masked_fill(torch.eye(5, dtype=torch.bool), float("-inf"))
    idx, ok = nearest_others(pair, alive, 2, key=-scores.detach())
    assert set(idx[0, 0].tolist()) == set(scores[0, 0].topk(2).indices.tolist()) and ok.all()
    net(pair, None, alive).sum().backward()
    assert net.score[0].weight.grad is not None and net.score[0].weight.grad.abs().sum() > 0


def test_h_mappo_trains_only_its_executor_and_takes_hungarian_goals(tmp_path):
    _, cfg, _ = method_config("h-mappo", ["num_envs=3", "ppo_epochs=1"])
    tr = MASPTrainer("mpe-5", cfg, seed=0)
    gm_before = [p.clone() for p in tr.nets.gm.parameters()]
    cae_before = [p.clone() for p in tr.nets.cae.parameters()]
    row = tr.iteration()
    assert row["gm_reward"] != row["gm_reward"]                  # NaN: no Goal Matcher trained
    assert all(torch.equal(a, b) for a, b in zip(gm_before, tr.nets.gm.parameters()))
    assert any(not torch.equal(a, b) for a, b in zip(cae_before, tr.nets.cae.parameters()))
    world = make("mpe-5", num_envs=2, seed=4)
    policy = make_policy("h-mappo", world, checkpoint=_saved(tr.nets, world, tmp_path / "hm.pt"))
    obs = world.reset()
    policy.reset(obs)
    policy.act(obs)
    assert torch.equal(policy.goals, hungarian_goals(obs["agent_pos"], obs["landmark_pos"], obs["alive"]))


def test_mage_x_assigns_goals_once_per_episode():
    _, cfg, _ = method_config("mage-x", ["num_envs=2", "ppo_epochs=1", "gm_ppo_epochs=1"])
    tr = MASPTrainer("mpe-5", cfg, seed=0)
    gm, _, _ = tr.collect()
    assert gm["actions"].shape[0] == 1                             # one Goal Matcher decision, at t = 0
    assert tr.nets.config.executor == "subgraph" and tr.nets.config.global_step > tr.horizon


def _saved(nets, world, path):
    save_weights(path, nets, world.scenario)
    return str(path)


def test_one_methods_weights_are_refused_by_another(tmp_path):
    world = make("mpe-5", num_envs=1, seed=0)
    path = _saved(MASPNets(NetConfig(goal_matcher="hungarian", executor="nearest")), world, tmp_path / "hm.pt")
    with pytest.raises(ValueError, match="these are h-mappo weights: use that method"):
        make_policy("mage-x", world, checkpoint=path)
    with pytest.raises(ValueError, match="expected {'goal_matcher': 'graph', 'executor': 'graph'}"):
        make_policy("masp", world, checkpoint=path)


def test_train_rejects_bad_methods_and_settings_before_writing(tmp_path, capsys):
    out = tmp_path / "run"
    for argv, msg in [(["--method", "h-greedy", "--scenario", "mpe-5"], "not a method trained on particle worlds"),
                      (["--method", "h-mappo", "--scenario", "mpe-5", "--set", "executor=graph"], "makes another one"),
                      (["--method", "masp-rg", "--scenario", "drone-5"], "not a method trained on drone worlds"),
                      (["--scenario", "mpe-5", "--set", "executor=nearest"], "no particle method has the settings")]:
        assert main(["train", *argv, "--out", str(out)]) == 2
        assert msg in capsys.readouterr().err
        assert not out.exists()


def test_train_without_method_takes_the_one_its_settings_make():
    assert method_config(None, ["goal_matcher=random"])[0] == "masp-rg"      # the ablations' recorded commands
    assert method_config(None, ["executor=subgraph"])[0] == "mage-x"
    assert method_config(None, [])[0] == "masp"
    assert method_config(None, ["executor=subgraph"])[1].net.global_step == 1000


def test_coverage_reward_is_simple_spreads_shape():
    from masp_lite.algos.goal_sources import coverage_reward
    agents = torch.tensor([[[0.0, 0.0], [3.0, 0.0]]])
    landmarks = torch.tensor([[[0.0, 0.05], [1.0, 0.0]]])
    alive = torch.tensor([[True, True]])
    r = coverage_reward(agents, landmarks, torch.tensor([[0, 2]]), alive, reach=0.1, world_size=4.0)
    team = 0.5 - (0.05 + 1.0) / 2 / 2.0                      # half covered; mean nearest distance / (world/2)
    torch.testing.assert_close(r, torch.tensor([[team, team - 2.0]]))
    r = coverage_reward(agents, landmarks, torch.tensor([[0, 0]]), torch.tensor([[False, True]]), 0.1, 4.0)
    assert r[0, 0] == 0 and r[0, 1] < team                   # a dropped agent covers nothing and earns 0


def test_goal_free_views_see_what_their_paper_says():
    from masp_lite.nets.baselines import AttentionPool, RadiusMean
    torch.manual_seed(2)
    pos = torch.tensor([[[0.0, 0.0], [0.5, 0.0], [3.0, 0.0]]])
    vel = torch.zeros_like(pos)
    alive = torch.ones(1, 3, dtype=torch.bool)
    radius = RadiusMean(6, 8)
    out = radius(pair_features(pos, vel), None, alive)
    far = pos.clone()
    far[0, 2] = torch.tensor([5.0, 1.0])                      # moves, still beyond the one-hop radius of agent 0
    torch.testing.assert_close(radius(pair_features(far, vel), None, alive)[0, 0], out[0, 0])
    pool = AttentionPool(6, 8)
    seen = pool(pair_features(far, vel), None, alive)[0, 0]   # attention sees every other agent
    assert not torch.allclose(seen, pool(pair_features(pos, vel), None, alive)[0, 0])
    alone = pool(pair_features(pos[:, :1], vel[:, :1]), None, alive[:, :1])
    assert torch.equal(alone, torch.zeros_like(alone))       # nobody else: nothing pooled


@pytest.mark.parametrize("method", ["mappo", "darl1n"])
def test_goal_free_baselines_train_without_goals(method, tmp_path):
    _, cfg, _ = method_config(method, ["num_envs=2", "ppo_epochs=1"])
    tr = MASPTrainer("mpe-5", cfg, seed=0)
    before = [p.clone() for p in tr.nets.cae.parameters()]
    row = tr.iteration()
    assert row["gm_reward"] != row["gm_reward"] and row["cae_reward"] == row["cae_reward"]
    assert any(not torch.equal(a, b) for a, b in zip(before, tr.nets.cae.parameters()))
    world = make("mpe-20to10", num_envs=2, seed=1)
    policy = make_policy(method, world, checkpoint=_saved(tr.nets, make("mpe-5", num_envs=1), tmp_path / "w.pt"),
                         any_scenario=True)
    obs = world.reset()
    policy.reset(obs)
    assert policy.act(obs).shape == (2, 20) and policy.goals is None
