"""The paper's RL baselines on drones: their 3-D parts, their training and their policies."""
import pytest
import torch

from masp_lite.algos.drone_trainer import DroneMASPTrainer
from masp_lite.algos.goal_sources import coverage_reward
from masp_lite.envs import make
from masp_lite.nets.baselines import distance_feature, far, landmark_features, nearest_others
from masp_lite.nets.drones import DRONE_SPEED, DroneNets
from masp_lite.nets.features import goal_features, pair_features
from masp_lite.policies import learned_methods, make_policy
from masp_lite.training import method_config, train
from masp_lite.weights import load_weights

BASELINES = sorted(m for m, e in learned_methods("drone").items() if e.get("group") == "baseline")
TINY = ["num_envs=2", "updates=1", "eval_every=0", "eval_episodes=2", "width=8", "checkpoint_every=1"]


def test_every_paper_baseline_has_a_drone_entry_with_the_paper_action():
    assert BASELINES == ["darl1n", "h-mappo", "htamp", "mage-x", "mappo"]
    for m in BASELINES:
        _, cfg, _ = method_config(m, [], "drone-5")
        assert cfg.net.action == "throttle" and cfg.net.world == "drone"
        assert {k: getattr(cfg.net, k) for k in ("goal_matcher", "executor")} == \
            {k: learned_methods("particle")[m]["nets"][k] for k in ("goal_matcher", "executor")}


def test_3d_pair_features_rank_by_the_3d_distance():
    pos = torch.tensor([[[0.0, 0.0, 1.0], [0.0, 0.0, 1.3], [0.5, 0.0, 1.0], [0.0, 0.0, 9.0]]])
    pair = pair_features(pos, torch.zeros_like(pos), 2.0, DRONE_SPEED)
    assert torch.allclose(distance_feature(pair)[0, 0], torch.tensor([0.0, 0.15, 0.25, 1.0]))
    idx, ok = nearest_others(pair, torch.ones(1, 4, dtype=torch.bool), 2)
    assert idx[0, 0].tolist() == [1, 2] and ok.all()
    assert far(8).tolist() == [0, 0, 0, 1, 0, 0, 0, 0] and far(6).tolist() == [0, 0, 1, 0, 0, 0]


def test_3d_landmark_features_are_the_goal_features_of_each_landmark_plus_covered():
    g = torch.Generator().manual_seed(0)
    pos, vel, lm = torch.rand(2, 3, 3, generator=g), torch.rand(2, 3, 3, generator=g), torch.rand(2, 4, 3, generator=g)
    covered = torch.tensor([[True, False, False, True], [False] * 4])
    f = landmark_features(pos, vel, lm, covered, DRONE_SPEED)
    assert f.shape == (2, 3, 4, 9)
    for j in range(4):
        goal = goal_features(pos, vel, lm[:, j:j + 1].expand(2, 3, 3), DRONE_SPEED)
        assert torch.allclose(f[:, :, j, :5], goal[..., :5]) and torch.allclose(f[:, :, j, 6:], goal[..., 5:])
        assert torch.equal(f[:, :, j, 5], covered[:, j:j + 1].float().expand(2, 3))


@pytest.mark.parametrize("method", BASELINES)
def test_a_baseline_trains_on_drones_and_flies_as_its_own_method(method, tmp_path):
    _, cfg, _ = method_config(method, TINY, "drone-5")
    train("drone-5", cfg, tmp_path, seed=0, progress=False)
    nets, _ = load_weights(tmp_path / "weights.pt", scenario="drone-5")
    assert isinstance(nets, DroneNets) and nets.config.team_size == (5 if method == "htamp" else 0)
    world = make("drone-5", num_envs=2, seed=0)
    obs = world.reset()
    policy = make_policy(method, world, checkpoint=str(tmp_path / "weights.pt"))
    policy.reset(obs)
    a = policy.act(obs)
    assert a.shape == (2, 5, 4) and a.abs().max() <= 1
    other = "mappo" if method == "darl1n" else "darl1n"
    with pytest.raises(ValueError, match=f"these are {method} weights"):
        make_policy(other, world, checkpoint=str(tmp_path / "weights.pt"))
    with pytest.raises(ValueError, match="drone-world networks.*particle world"):
        make_policy(method, make("mpe-5", num_envs=1), checkpoint=str(tmp_path / "weights.pt"))
    with pytest.raises(ValueError, match="trained for 'drone-5'; expected weights for 'drone-20'"):
        make_policy(method, make("drone-20", num_envs=1), checkpoint=str(tmp_path / "weights.pt"))


@pytest.mark.parametrize("method", ["h-mappo", "mappo"])
def test_graph_baselines_fine_tune_at_another_team_size(method, tmp_path):
    _, cfg, _ = method_config(method, TINY, "drone-5")
    nets = DroneNets(cfg.net)
    world = make("drone-20", num_envs=1, seed=0)
    obs = world.reset()
    goals = None if cfg.net.goal_matcher == "none" else torch.arange(20).unsqueeze(0)
    (mean, _), v = nets.cae_forward(nets.cae_inputs(obs, goals, torch.arange(20).unsqueeze(0)), obs, 500)
    assert mean.shape == (1, 20, 4) and v.shape == (1, 20)


def test_a_goal_free_drone_that_crashes_is_charged_the_team_distance_for_the_steps_left():
    _, cfg, _ = method_config("mappo", TINY, "drone-5")
    tr = DroneMASPTrainer("drone-5", cfg, seed=0)
    obs = tr.world.reset()
    alive = obs["alive"].clone()
    after = dict(obs, alive=alive.clone())
    after["alive"][0, 1] = False
    hits = torch.zeros(2, 5, dtype=torch.long)
    hits[0, 1] = 1
    r = tr.executor_reward(after, None, {"agent_collisions": hits}, alive, t=10)
    sc = tr.world.scenario
    base = coverage_reward(obs["agent_pos"], obs["landmark_pos"], hits, alive, sc.reach_distance, sc.world_size)
    team = torch.cdist(obs["landmark_pos"][0], obs["agent_pos"][0]).min(-1).values.mean()
    assert torch.allclose(r[0, 1], base[0, 1] - (sc.horizon - 11) * team / (sc.world_size / 2))
    mask = torch.ones_like(r, dtype=torch.bool)
    mask[0, 1] = False
    assert torch.equal(r[mask], base[mask])  # only the crashed drone pays
