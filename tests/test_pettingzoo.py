"""The PettingZoo face: PettingZoo's own API/seed/render tests, spaces, observations, team change."""
import functools
import warnings

import numpy as np
import pytest
import torch
from pettingzoo.test import parallel_api_test, parallel_seed_test, render_test
from pettingzoo.utils.conversions import parallel_to_aec

from masp_lite.envs import MPE2_WORLD, parallel_env
from masp_lite.envs.pettingzoo.particle import LOCAL_RATIO

SCENARIOS = ["mpe-5", "mpe-50", "mpe-50to20", "mpe-20", "mpe-20to10"]


@pytest.mark.parametrize("name", SCENARIOS)
def test_pettingzoo_parallel_api_and_seed_tests(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the API test passes reset(options={"options": 1})
        parallel_api_test(parallel_env(name), num_cycles=200)
    parallel_seed_test(functools.partial(parallel_env, name))


@pytest.mark.parametrize("name", ["mpe-5", "mpe-50", "mpe-50to20"])
def test_pettingzoo_render_test(name):
    render_test(lambda render_mode=None: parallel_to_aec(parallel_env(name, render_mode=render_mode)))


def test_rgb_array_shows_the_bodies():
    env = parallel_env("mpe-5", render_mode="rgb_array")
    env.reset(seed=0)
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3
    assert (img < 250).any(axis=2).mean() > 0.005  # something besides the white background
    env.close()


def test_spaces_and_agent_names():
    env = parallel_env("mpe-20", num_obstacles=7)
    n, k = 20, 7
    assert env.possible_agents == [f"agent_{i}" for i in range(n)]
    obs, infos = env.reset(seed=0)
    for a in env.agents:
        assert env.action_space(a).n == 5
        space = env.observation_space(a)
        assert space.shape == (7 * n - 1 + 2 * k,) and space.dtype == np.float32
        assert obs[a].shape == space.shape and obs[a].dtype == np.float32 and space.contains(obs[a])
        assert set(infos[a]) == {"collisions", "covered_landmarks"}


def test_observation_layout_matches_the_docstring_table():
    env = parallel_env("mpe-5", num_agents=3, num_obstacles=2)
    pos = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    vel = np.array([[0.1, 0.2], [0.3, 0.4], [-0.5, 0.6]])
    lms = np.array([[0.7, 0.7], [-0.7, 0.7], [0.7, -0.7]])
    obst = np.array([[-0.5, -0.5], [0.5, 0.5]])
    obs, _ = env.reset(options={"agent_pos": pos, "agent_vel": vel, "landmark_pos": lms, "obstacle_pos": obst})
    o = obs["agent_1"].astype(np.float64)
    expected = np.concatenate([vel[1], pos[1], (lms - pos[1]).ravel(),
                               (pos[[0, 2]] - pos[1]).ravel(), (vel[[0, 2]] - vel[1]).ravel(),
                               [1.0, 1.0], (obst - pos[1]).ravel()])
    np.testing.assert_allclose(o, expected, atol=1e-6)
    np.testing.assert_allclose(env.agent_pos, pos, atol=1e-6)
    np.testing.assert_allclose(env.agent_vel, vel, atol=1e-6)
    assert env.world.num_envs == 1


def test_global_state_is_every_body_absolute():
    env = parallel_env("mpe-20to10", num_obstacles=3)
    env.reset(seed=1)
    for _ in range(env.scenario.change_step):
        env.step({a: 4 for a in env.agents})
    s, w = env.state(), env.world
    assert env.state_space.contains(s) and s.shape == (7 * 20 + 2 * 3,)
    np.testing.assert_array_equal(s[:40], w.agent_pos[0].numpy().ravel())
    assert s[80:100].sum() == env.scenario.team_after and s[-6:].tolist() == w.obstacle_pos[0].ravel().tolist()


def test_team_change_terminates_dropped_agents_once_and_truncates_the_rest():
    env = parallel_env("mpe-20to10")
    sc = env.scenario
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    for t in range(1, sc.horizon + 1):
        acting = list(env.agents)
        obs, rew, term, trunc, info = env.step({a: int(rng.integers(5)) for a in acting})
        assert set(obs) == set(rew) == set(term) == set(trunc) == set(info) == set(acting)
        if t < sc.change_step:
            assert not any(term.values()) and len(env.agents) == sc.num_agents
        elif t == sc.change_step:
            gone = [a for a in acting if term[a]]
            assert len(gone) == sc.num_agents - sc.team_after and len(env.agents) == sc.team_after
            alive = env.world.alive[0].numpy()
            assert all(not alive[int(a.split("_")[1])] for a in gone)
            survivor = env.agents[0]
            flags = obs[survivor][-2 * sc.num_obstacles - (sc.num_agents - 1):-2 * sc.num_obstacles]
            assert flags.sum() == sc.team_after - 1  # the others' alive flags
        else:
            assert not any(term.values())
        if t < sc.horizon:
            assert not any(trunc.values())
    assert all(trunc.values()) and env.agents == []
    with pytest.raises(ValueError, match="reset"):
        env.step({})


def test_dropped_agents_slots_are_zero():
    env = parallel_env("mpe-5", num_agents=3, num_obstacles=0, team_after=1, change_step=1)
    env.reset(seed=0, options={"keep": np.array([False, True, False])})
    obs, *_ = env.step({a: 2 for a in env.agents})
    n = 3
    o = obs["agent_1"]
    others = slice(4 + 2 * n, 4 + 2 * n + 4 * (n - 1))
    assert not o[others].any() and not o[4 + 2 * n + 4 * (n - 1):].any()  # positions, velocities, flags
    assert env.agents == ["agent_1"]


def test_reward_is_simple_spread_with_local_ratio():
    env = parallel_env("mpe-5", num_agents=2, num_obstacles=0)
    pos = np.array([[0.0, 0.0], [0.25, 0.0]])
    lms = np.array([[0.0, 0.6], [0.8, 0.0]])
    env.reset(options={"agent_pos": pos, "landmark_pos": lms, "agent_vel": [[0.0, 0.0], [-1.0, 0.0]]})
    _, rew, *_ = env.step({"agent_0": 0, "agent_1": 0})
    p = env.agent_pos
    d = np.linalg.norm(p[:, None] - lms[None], axis=-1).min(axis=0).sum()
    touching = float(np.linalg.norm(p[0] - p[1]) < 0.2)
    assert touching == 1.0  # agent 1 moved to 0.15 from agent 0
    for a in ("agent_0", "agent_1"):
        assert rew[a] == pytest.approx(-(1 - LOCAL_RATIO) * d - LOCAL_RATIO * touching)


def test_seeded_resets_repeat_and_unseeded_resets_move_on():
    env = parallel_env("mpe-20")
    first, _ = env.reset(seed=5)
    second, _ = env.reset()
    again, _ = env.reset(seed=5)
    assert all(np.array_equal(first[a], again[a]) for a in first)
    assert not np.array_equal(first["agent_0"], second["agent_0"])


def test_numpy_and_torch_integer_actions_are_accepted():
    env = parallel_env("mpe-5")
    env.reset(seed=0)
    acts = {a: v for a, v in zip(env.agents, [np.int64(1), np.int32(2), torch.tensor(3), 4, np.array(0)])}
    env.step(acts)
    assert env.world.t.tolist() == [1]


def test_drone_scenarios_are_handed_to_the_drone_module(monkeypatch):
    import sys
    import types

    calls = []
    fake = types.ModuleType("masp_lite.envs.pettingzoo.drones")
    fake.DroneParallelEnv = lambda sc, render_mode=None: calls.append((sc.name, sc.horizon, render_mode)) or "drone"
    monkeypatch.setitem(sys.modules, "masp_lite.envs.pettingzoo.drones", fake)
    assert parallel_env("drone-5", render_mode="rgb_array", horizon=10) == "drone"
    assert calls == [("drone-5", 10, "rgb_array")]


def test_rewards_and_positions_match_mpe2_simple_spread():
    """Same start and actions as mpe2's simple_spread_v3 (agent size 0.1): same rewards."""
    simple_spread = pytest.importorskip("mpe2.simple_spread_v3")
    n, steps = 6, 40
    rng = np.random.default_rng(7)
    centres = np.array([[-0.5, -0.5], [0.5, 0.0], [-0.3, 0.6]])
    pos = np.concatenate([centres - [0.1025, 0], centres + [0.1025, 0]])
    vel = np.concatenate([np.tile([1.2, 0.0], (3, 1)), np.tile([-1.2, 0.1], (3, 1))])
    lms = rng.uniform(-0.9, 0.9, (n, 2))
    ref = simple_spread.parallel_env(N=n, max_cycles=steps)
    ref.reset(seed=0)
    for i, agent in enumerate(ref.unwrapped.world.agents):
        agent.size = 0.1
        agent.state.p_pos, agent.state.p_vel = pos[i].copy(), vel[i].copy()
    for i, lm in enumerate(ref.unwrapped.world.landmarks):
        lm.state.p_pos = lms[i].copy()
    env = parallel_env("mpe-5", num_agents=n, num_obstacles=0, world_size=4.0, horizon=steps, **MPE2_WORLD)
    env.reset(options={"agent_pos": pos, "agent_vel": vel, "landmark_pos": lms})
    penalties = 0
    for _ in range(steps):
        acts = {a: int(rng.integers(5)) for a in env.agents}
        _, want, *_ = ref.step(acts)
        _, got, _, _, infos = env.step(acts)
        for a in acts:
            assert got[a] == pytest.approx(want[a], abs=1e-4)
        penalties += sum(info["collisions"] for info in infos.values())
        mpe_pos = np.stack([x.state.p_pos for x in ref.unwrapped.world.agents])
        np.testing.assert_allclose(env.agent_pos, mpe_pos, atol=1e-4)
    assert penalties > 0, "the start state was meant to produce collision penalties"
    assert env.agents == [] and ref.agents == []
