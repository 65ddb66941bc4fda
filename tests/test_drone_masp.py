"""MASP on drones: the Gaussian executor, its PPO pieces, the drone trainer, the policy and bad input."""
import math

import pytest
import torch

from masp_lite.algos.drone_trainer import DroneMASPTrainer, crash_charge, motor_commands, velocity_controller
from masp_lite.config import NetConfig
from masp_lite.envs import make
from masp_lite.envs.drone_model import CONTROL_DT, HOVER_COMMAND
from masp_lite.nets.drones import DRONE_SPEED, DroneNets, drone_state_features, gaussian_entropy, gaussian_log_prob
from masp_lite.policies import make_policy
from masp_lite.training import method_config, train
from masp_lite.weights import load_weights, save_weights

TINY = ["num_envs=2", "updates=2", "eval_every=0", "eval_episodes=2", "width=8", "checkpoint_every=1"]


def test_gaussian_log_prob_and_entropy_are_torchs():
    g = torch.Generator().manual_seed(0)
    mean, log_std = torch.randn(3, 5, 4, generator=g), torch.randn(4, generator=g) * 0.5
    a = torch.randn(3, 5, 4, generator=g)
    ref = torch.distributions.Normal(mean, log_std.exp())
    assert torch.allclose(gaussian_log_prob(mean, log_std, a), ref.log_prob(a).sum(-1), atol=1e-5)
    assert torch.allclose(gaussian_entropy(log_std, (3, 5)), ref.entropy().sum(-1), atol=1e-5)


def test_untrained_executor_asks_for_hover_and_runs_any_team_size():
    nets = DroneNets(NetConfig(action="throttle", width=8))
    for n in (5, 20):
        world = make(f"drone-{n}", num_envs=2, seed=0)
        obs = world.reset()
        goals = torch.arange(n).expand(2, n)
        mean, log_std = nets.cae_logits(nets.cae_inputs(obs, goals, torch.arange(n).expand(2, n)))
        assert mean.shape == (2, n, 4) and log_std.shape == (4,)
        assert (mean - HOVER_COMMAND).abs().max() < 0.05
        scale = world.scenario.world_size / 2
        logits = nets.gm_logits(obs, scale)
        assert logits.shape == (2, n, n)
        both = nets.gm_forward(obs, scale, world.horizon)  # training's one pass: the same numbers
        assert torch.equal(both[0], logits) and torch.equal(both[1], nets.gm_value(obs, scale, world.horizon))
    st = drone_state_features(obs)
    assert st.shape == (2, 20, 17)
    assert torch.allclose(st[..., :9], torch.eye(3).flatten().expand(2, 20, 9), atol=1e-6)  # level at reset


def test_velocity_executor_starts_still():
    nets = DroneNets(NetConfig(action="velocity", width=8))
    world = make("drone-5", num_envs=1, seed=0)
    obs = world.reset()
    mean, _ = nets.cae_logits(nets.cae_inputs(obs, torch.arange(5)[None], torch.arange(5)[None]))
    assert mean.shape == (1, 5, 3) and mean.abs().max() < 0.05


def test_velocity_actions_are_flown_by_the_controller():
    world = make("drone-5", num_envs=1, seed=0)
    obs = world.reset()
    wild = torch.full((1, 5, 4), 3.0)
    assert torch.equal(motor_commands(wild, obs), torch.ones(1, 5, 4))        # throttle: clipped, nothing more
    controller = velocity_controller()
    ask = torch.zeros(1, 5, 3)
    ask[0, 0] = torch.tensor([2.0, 0.0, 0.0])                                 # clipped to 1: DRONE_SPEED along x
    start = obs["agent_pos"].clone()
    for _ in range(40):
        cmd = motor_commands(ask, obs, controller)
        assert cmd.shape == (1, 5, 4) and cmd.abs().max() <= 1
        obs, _ = world.step(cmd)
    moved = obs["agent_pos"] - start
    assert moved[0, 0, 0] > 0.3 * DRONE_SPEED * 40 * CONTROL_DT and moved[0, 0, 1:].abs().max() < 0.3
    assert moved[0, 1:].abs().max() < 0.1 and bool(obs["alive"].all())   # asked to stay: they hover


def test_crash_charge_makes_crashing_no_better_than_hovering():
    dist = torch.tensor([[2.0, 4.0]])
    crashed = torch.tensor([[True, False]])
    c = crash_charge(dist, crashed, steps_left=10, world_size=8.0)
    assert c.tolist() == [[10 * 2.0 / 4.0, 0.0]]  # exactly the distance penalty of 10 more steps at the crash site


def test_a_drone_run_trains_resumes_and_is_deterministic(tmp_path):
    _, cfg, _ = method_config(None, [*TINY, "goal_matcher=hungarian"], "drone-5")
    whole = train("drone-5", cfg, tmp_path / "whole", seed=1, progress=False)

    class Stop(Exception):
        pass

    def stop(trainer):
        if trainer.iterations == 1:
            raise Stop

    with pytest.raises(Stop):
        train("drone-5", cfg, tmp_path / "cut", seed=1, progress=False, on_iteration=stop)
    train("drone-5", cfg, tmp_path / "cut", seed=1, progress=False, resume=True)
    a = torch.load(tmp_path / "whole" / "state.pt", weights_only=True)
    b = torch.load(tmp_path / "cut" / "state.pt", weights_only=True)
    for k in a["nets"]:
        assert torch.equal(a["nets"][k], b["nets"][k]), k
    assert whole["env_steps"] == 2 * 2 * 300
    nets, rec = load_weights(tmp_path / "whole" / "weights.pt", scenario="drone-5")
    assert isinstance(nets, DroneNets) and rec["arch"]["action"] == "throttle"
    # the curriculum's next stage: the Goal Matcher trained too, from the executor-only stage's weights
    _, cfg2, _ = method_config(None, [*TINY, "updates=1"], "drone-5")
    train("drone-5", cfg2, tmp_path / "stage2", seed=1, progress=False, init=tmp_path / "whole" / "weights.pt")
    after, _ = load_weights(tmp_path / "stage2" / "weights.pt", scenario="drone-5")
    assert after.config.goal_matcher == "graph"
    before, now = nets.state_dict(), after.state_dict()
    assert any(not torch.equal(before[k], now[k]) for k in now if k.startswith("gm."))  # the Goal Matcher learned
    with pytest.raises(ValueError, match="differs from the configured"):  # another layout: refused
        _, wide, _ = method_config(None, [*TINY, "width=16"], "drone-5")
        train("drone-5", wide, tmp_path / "wide", progress=False, init=tmp_path / "whole" / "weights.pt")


def test_the_drone_trainer_learns_the_goal_matcher_too():
    _, cfg, _ = method_config("masp-velocity", TINY, "drone-5")
    tr = DroneMASPTrainer("drone-5", cfg, seed=0)
    row = tr.iteration()
    assert math.isfinite(row["gm_policy_loss"]) and math.isfinite(row["cae_policy_loss"])


def test_policy_flies_shipped_shapes_and_refuses_the_wrong_weights(tmp_path):
    path = tmp_path / "drone.pt"
    save_weights(path, DroneNets(NetConfig(action="throttle", width=8)), "drone-5")
    world = make("drone-5", num_envs=3, seed=0)
    obs = world.reset()
    policy = make_policy("masp", world, checkpoint=str(path))
    policy.reset(obs)
    a = policy.act(obs)
    assert a.shape == (3, 5, 4) and a.dtype == torch.float32 and a.abs().max() <= 1
    world.step(a)
    with pytest.raises(ValueError, match="masp-velocity|expected 'velocity'"):
        make_policy("masp-velocity", world, checkpoint=str(path))
    with pytest.raises(ValueError, match="drone-world networks.*particle world"):
        make_policy("masp", make("mpe-5", num_envs=1), checkpoint=str(path))
    particle = tmp_path / "particle.pt"
    from masp_lite.nets.masp import MASPNets
    save_weights(particle, MASPNets(width=8), "mpe-5")
    with pytest.raises(ValueError, match="particle-world networks.*drone world"):
        make_policy("masp", world, checkpoint=str(particle))


@pytest.mark.parametrize("method, sets, match", [
    ("masp-rg", [], "not a method trained on drone worlds"),
    ("masp", ["action=velocity"], "makes another one"),
    ("h-mappo", ["executor=graph"], "makes another one"),
    (None, ["executor=nearest"], "no drone method has the settings"),
])
def test_bad_drone_training_settings_are_one_clear_error(method, sets, match):
    with pytest.raises(ValueError, match=match):
        method_config(method, sets, "drone-5")


def test_drone_actions_refused_on_particle_worlds():
    with pytest.raises(ValueError, match="action is for drone scenarios"):
        method_config(None, ["action=throttle"], "mpe-5")
