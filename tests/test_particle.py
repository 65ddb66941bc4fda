"""The batched particle world: hand-worked physics, mpe2 agreement, spawns, team change, seeds."""
import math

import numpy as np
import pytest
import torch

from masp_lite.envs import MPE2_WORLD, PHYSICS, SCENARIOS, ParticleWorld, make, parallel_env, scenario_names
from masp_lite.envs.scenarios import get_scenario

DT, DAMP, SENS = PHYSICS["dt"], PHYSICS["damping"], PHYSICS["sensitivity"]
PARTICLE = scenario_names("particle")


def lone_agent(**kw):
    """One agent, no obstacles, float64, at rest at the origin; mpe2's update order unless ``kw`` says."""
    w = ParticleWorld("mpe-5", num_agents=1, num_obstacles=0, horizon=200, dtype=torch.float64, seed=0,
                      **{**MPE2_WORLD, **kw})
    w.reset(options={"agent_pos": [[0.0, 0.0]], "landmark_pos": [[1.0, 1.0]]})
    return w


def close(actual, expected, atol=1e-12):
    np.testing.assert_allclose(actual.numpy(), np.asarray(expected, dtype=np.float64), rtol=0, atol=atol)


def act(w, ids):
    return w.step(torch.tensor(ids, dtype=torch.long).reshape(w.num_envs, w.num_agents))


def place(w, agents, obstacles=None):
    """Put bodies anywhere mid-episode (overlapping, say), then refresh the contact geometry."""
    w.agent_pos = torch.tensor(agents, dtype=w.dtype).reshape(1, -1, 2)
    if obstacles is not None:
        w.obstacle_pos = torch.tensor(obstacles, dtype=w.dtype).reshape(1, -1, 2)
    w._geometry()


# ------------------------------------------------------------------ hand-worked physics
def test_accelerating_from_rest_matches_hand_computation():
    w = lone_agent()
    # step 1: x = 0 (old velocity 0), v = 0.5; step 2: x = 0.05, v = 0.875; step 3: x = 0.1375, v = 1.15625
    expected = [(0.0, 0.5), (0.05, 0.875), (0.1375, 1.15625)]
    for x, v in expected:
        act(w, [2])
        assert w.agent_pos[0, 0].tolist() == pytest.approx([x, 0.0], abs=1e-12)
        assert w.agent_vel[0, 0].tolist() == pytest.approx([v, 0.0], abs=1e-12)


def test_velocity_first_integration_moves_in_the_step_of_the_push():
    w = make("mpe-5", num_envs=1, num_agents=1, num_obstacles=0, seed=0, integration="velocity_first")
    w.reset(options={"agent_pos": torch.zeros(1, 2), "landmark_pos": torch.tensor([[0.9, 0.9]])})
    # the original MPE: v = 0.5 then x = 0.05; v = 0.875 then x = 0.1375; ...
    for x, v in [(0.05, 0.5), (0.1375, 0.875), (0.253125, 1.15625)]:
        act(w, [2])
        assert w.agent_pos[0, 0].tolist() == pytest.approx([x, 0.0], abs=1e-6)
        assert w.agent_vel[0, 0].tolist() == pytest.approx([v, 0.0], abs=1e-6)
    assert make("mpe-5").scenario.integration == "velocity_first"  # every mpe-* preset is the paper's world
    with pytest.raises(ValueError, match="integration in"):
        make("mpe-5", integration="rk4")
    with pytest.raises(ValueError, match="drone"):
        get_scenario("drone-5", integration="velocity_first")


def test_terminal_speed_is_two_metres_per_second():
    w = lone_agent()
    for _ in range(80):
        act(w, [4])  # +y
    # v_n = 0.5 (1 - 0.75^n) / 0.25 -> 2
    assert w.agent_vel[0, 0].tolist() == pytest.approx([0.0, SENS * DT / DAMP], abs=1e-8)
    assert SENS * DT / DAMP == pytest.approx(2.0)


def soft_contact(dist, dist_min):
    k = PHYSICS["contact_margin"]
    return PHYSICS["contact_force"] * k * math.log1p(math.exp(-(dist - dist_min) / k))


def test_two_overlapping_agents_push_apart_with_mpe_contact_force():
    w = ParticleWorld("mpe-5", num_agents=2, num_obstacles=0, dtype=torch.float64, seed=0, **MPE2_WORLD)
    place(w, [[0.0, 0.0], [0.15, 0.0]])
    obs, info = act(w, [0, 0])
    f = soft_contact(0.15, 0.2)               # along delta / dist = (-1, 0) for agent 0
    assert f == pytest.approx(5.0, rel=1e-6)  # ~ contact_force * penetration (0.05)
    close(w.agent_vel[0], [[-f * DT, 0.0], [f * DT, 0.0]])
    close(w.agent_pos[0], [[0.0, 0.0], [0.15, 0.0]])  # moved with the old velocity, 0
    assert info["collisions"].tolist() == [1] and info["agent_collisions"].tolist() == [[1, 1]]


def test_contact_force_direction_is_along_the_centre_line():
    w = ParticleWorld("mpe-5", num_agents=2, num_obstacles=0, dtype=torch.float64, seed=0, **MPE2_WORLD)
    place(w, [[0.0, 0.0], [0.09, 0.12]])      # dist 0.15 along (0.6, 0.8)
    act(w, [0, 0])
    f = soft_contact(0.15, 0.2) * DT
    close(w.agent_vel[0], [[-0.6 * f, -0.8 * f], [0.6 * f, 0.8 * f]])


def test_immovable_obstacle_pushes_the_agent_and_does_not_move():
    w = ParticleWorld("mpe-5", num_agents=1, num_obstacles=1, dtype=torch.float64, seed=0, **MPE2_WORLD)
    place(w, [[0.0, 0.0]], obstacles=[[0.15, 0.0]])
    _, info = act(w, [0])
    f = soft_contact(0.15, w.scenario.agent_radius + w.scenario.obstacle_radius)
    assert w.agent_vel[0, 0].tolist() == pytest.approx([-f * DT, 0.0], abs=1e-12)
    assert w.obstacle_pos[0, 0].tolist() == [0.15, 0.0]
    assert info["collisions"].tolist() == [1] and info["agent_collisions"].tolist() == [[1]]


def test_obstacle_deflects_a_passing_agent():
    w = ParticleWorld("mpe-5", num_agents=1, num_obstacles=1, horizon=60, dtype=torch.float64, seed=0, **MPE2_WORLD)
    w.reset(options={"agent_pos": [[-0.5, -0.1]], "obstacle_pos": [[0.0, 0.0]], "landmark_pos": [[1, 1]],
                     "agent_vel": [[2.0, 0.0]]})
    hits = 0
    for _ in range(6):
        _, info = act(w, [0])
        hits += int(info["collisions"])
    assert hits > 0 and float(w.agent_vel[0, 0, 1]) < 0  # pushed away, below the obstacle
    assert w.obstacle_pos[0, 0].tolist() == [0.0, 0.0]


def test_head_on_push_tunnels_through_like_mpe():
    """MPE's contacts are soft (force 100 N/m of penetration, dt 0.1): a steady push goes through."""
    w = ParticleWorld("mpe-5", num_agents=1, num_obstacles=1, horizon=60, dtype=torch.float64, seed=0, **MPE2_WORLD)
    w.reset(options={"agent_pos": [[-0.25, 0.0]], "obstacle_pos": [[0.0, 0.0]], "landmark_pos": [[1, 1]]})
    xs = [float(act(w, [2])[0]["agent_pos"][0, 0, 0]) for _ in range(8)]
    assert xs[0] == -0.25 and xs[-1] > 0.2


def test_landmarks_do_not_collide_and_are_covered():
    w = ParticleWorld("mpe-5", num_agents=1, num_obstacles=0, dtype=torch.float64, seed=0, **MPE2_WORLD)
    obs = w.reset(options={"agent_pos": [[0.3, 0.3]], "landmark_pos": [[0.32, 0.3]]})
    assert obs["covered"].tolist() == [[True]]
    _, info = act(w, [0])
    assert w.agent_vel.abs().max() == 0 and info["collisions"].tolist() == [0]
    assert info["covered"].tolist() == [[True]] and info["reached"].tolist() == [[True]]


# ------------------------------------------------------------------ against mpe2
def run_against_mpe2(dtype, obstacles, n=8, steps=60):
    """Same start state and random actions in mpe2 and here; worst position gap and contact counts.

    mpe2's agents get our radius 0.1; our obstacles enter mpe2 as extra immovable landmarks
    that collide, which is exactly what an obstacle is.
    """
    simple_spread = pytest.importorskip("mpe2.simple_spread_v3")
    from mpe2._mpe_utils.core import Landmark

    rng = np.random.default_rng(3)
    # four pairs of agents 0.205 apart heading into each other: contacts from the first step
    centres = np.array([[-0.6, -0.6], [0.6, -0.6], [-0.6, 0.6], [0.6, 0.6]])
    pos = np.concatenate([centres - [0.1025, 0], centres + [0.1025, 0]])
    vel = np.concatenate([np.tile([1.5, 0.2], (4, 1)), np.tile([-1.5, 0.0], (4, 1))])
    obstacles = np.asarray(obstacles, dtype=np.float64).reshape(-1, 2)
    lms = np.array([[x, y] for x in (-0.9, -0.3, 0.3, 0.9) for y in (-0.15, 0.15)])
    actions = rng.integers(0, 5, (steps, n))

    ref = simple_spread.parallel_env(N=n, max_cycles=steps + 5)
    ref.reset(seed=0)
    world = ref.unwrapped.world
    for i, agent in enumerate(world.agents):
        agent.size = 0.1
        agent.state.p_pos, agent.state.p_vel = pos[i].copy(), vel[i].copy()
    for i, lm in enumerate(world.landmarks):
        lm.state.p_pos = lms[i].copy()
    for xy in obstacles:
        ob = Landmark()
        ob.size, ob.collide, ob.movable, ob.color = 0.1, True, False, np.zeros(3)
        ob.state.p_pos, ob.state.p_vel = xy.copy(), np.zeros(2)
        world.landmarks.append(ob)

    w = ParticleWorld("mpe-5", num_agents=n, num_obstacles=len(obstacles), world_size=4.0, horizon=steps,
                      seed=0, dtype=dtype, **MPE2_WORLD)
    w.reset(options={"agent_pos": pos, "agent_vel": vel, "landmark_pos": lms, "obstacle_pos": obstacles})
    contacts, obstacle_contacts, worst = 0, 0, 0.0
    for t in range(steps):
        ref.step({f"agent_{i}": int(actions[t, i]) for i in range(n)})
        _, info = w.step(torch.as_tensor(actions[t]).reshape(1, n))
        contacts += int(info["collisions"])
        obstacle_contacts += int(2 * info["collisions"] - info["agent_collisions"].sum())
        mpe_pos = np.stack([a.state.p_pos for a in world.agents])
        worst = max(worst, float(np.abs(w.agent_pos[0].double().numpy() - mpe_pos).max()))
    return worst, contacts, obstacle_contacts


def test_matches_mpe2_in_float32_for_60_steps_with_collisions():
    worst, contacts, _ = run_against_mpe2(torch.float32, obstacles=[])
    assert contacts > 0, "the start state was meant to produce collisions"
    assert worst < 1e-4


def test_matches_mpe2_exactly_in_float64_with_obstacles():
    # In float32, grazing contacts (force gradient ~ contact_force / margin) amplify rounding,
    # so the exactness of the physics, obstacles included, is checked in float64.
    worst, contacts, obstacle_contacts = run_against_mpe2(torch.float64, obstacles=[[0.0, -0.45], [-0.6, 0.9]])
    assert contacts > obstacle_contacts > 0, "the start state was meant to produce both kinds of contact"
    assert worst < 1e-9


# ------------------------------------------------------------------ spawns
def assert_valid_spawn(w):
    sc = w.scenario
    a, o, lm = (x.double() for x in (w.agent_pos, w.obstacle_pos, w.landmark_pos))

    def min_gap(x, y, same):
        d = torch.cdist(x, y)
        if same:
            d = d + torch.eye(x.shape[1], dtype=d.dtype) * 1e9
        return float(d.min()) if d.numel() else math.inf

    assert min_gap(a, a, True) >= 2 * sc.agent_radius
    assert min_gap(a, o, False) >= sc.agent_radius + sc.obstacle_radius
    assert min_gap(o, o, True) >= 2 * sc.obstacle_radius
    assert min_gap(lm, o, False) >= sc.landmark_radius + sc.obstacle_radius
    for x, r in ((a, sc.agent_radius), (o, sc.obstacle_radius), (lm, sc.landmark_radius)):
        assert float(x.abs().max()) <= sc.world_size / 2 - r + 1e-9


@pytest.mark.parametrize("name", PARTICLE)
def test_spawns_do_not_overlap_and_stay_inside(name):
    w = make(name, num_envs=16, seed=1)
    assert_valid_spawn(w)
    w.reset(env_ids=[0, 3])
    assert_valid_spawn(w)


def test_a_given_overlapping_start_is_accepted_and_contact_pushes_the_agents_apart():
    """As in MPE: reset(options=...) may start agents in contact, with each other or with an obstacle."""
    for integration in ("mpe2", "velocity_first"):
        w = ParticleWorld("mpe-5", num_agents=3, num_obstacles=1, dtype=torch.float64, seed=0, integration=integration)
        w.reset(options={"agent_pos": [[0.0, 0.0], [0.1, 0.0], [-0.6, 0.45]], "obstacle_pos": [[-0.6, 0.6]],
                         "landmark_pos": [[0.8, 0.8], [-0.8, -0.8], [0.8, -0.8]]})
        assert w.collisions.tolist() == [2] and w.agent_collisions.tolist() == [[1, 1, 1]]  # counted at t = 0
        gaps = [(0.1, 0.15)]
        for _ in range(3):
            act(w, [0, 0, 0])
            gaps.append((float((w.agent_pos[0, 1] - w.agent_pos[0, 0]).norm()),
                         float((w.agent_pos[0, 2] - w.obstacle_pos[0, 0]).norm())))
        assert all(b[0] > a[0] and b[1] > a[1] for a, b in zip(gaps[1:], gaps[2:])), gaps  # apart, steadily
        assert gaps[-1][0] > 2 * w.scenario.agent_radius and gaps[-1][1] > 0.2   # out of contact within 3 steps
        assert w.obstacle_pos[0, 0].tolist() == [-0.6, 0.6] and torch.isfinite(w.agent_pos).all()
    env = parallel_env("mpe-5")                                                   # the PettingZoo face too
    env.reset(seed=0, options={"agent_pos": [[0, 0], [0.1, 0], [0.6, 0], [0.9, 0], [-0.6, 0]]})
    assert env.world.collisions.tolist() == [1]


def test_random_spawns_keep_clear_of_given_bodies():
    """Only given bodies may overlap: what reset draws stays apart from everything, given or drawn."""
    agents = torch.tensor([[-0.7, -0.7], [-0.7, 0.7], [0.7, -0.7], [0.7, 0.7], [0.0, 0.0]])
    w = make("mpe-5", num_envs=64, seed=3)
    w.reset(options={"agent_pos": agents})                      # obstacles and landmarks drawn around them
    assert_valid_spawn(w)
    w.reset(options={"landmark_pos": agents})                   # obstacles drawn clear of given landmarks
    assert_valid_spawn(w)


def test_spawns_for_a_hundred_agents():
    w = make("mpe-50", num_envs=4, seed=2, num_agents=100)
    assert w.agent_pos.shape == (4, 100, 2)
    assert_valid_spawn(w)


# ------------------------------------------------------------------ team-size change
@pytest.mark.parametrize("name", ["mpe-20to10", "mpe-50to20"])
def test_team_shrinks_exactly_after_change_step(name):
    w = make(name, num_envs=6, seed=4)
    sc, gen = w.scenario, torch.Generator().manual_seed(0)
    assert sc.change_step == sc.horizon // 3
    frozen = None
    for t in range(1, sc.horizon + 1):
        _, info = w.step(torch.randint(0, 5, (6, sc.num_agents), generator=gen))
        alive = info["alive"]
        if t < sc.change_step:
            assert alive.all()
            continue
        assert (alive.sum(1) == sc.team_after).all()
        dropped = ~alive
        assert (info["agent_collisions"][dropped] == 0).all()
        assert (w.agent_vel[dropped] == 0).all()  # leavers stop at once
        if frozen is not None:  # and stay where they left
            assert torch.equal(w.agent_pos[dropped], frozen)
        frozen = w.agent_pos[dropped].clone()
    assert bool(w.done.all())


def test_dropped_agent_neither_collides_nor_covers():
    w = ParticleWorld("mpe-5", num_agents=2, num_obstacles=0, team_after=1, change_step=1,
                      dtype=torch.float64, seed=0)
    w.reset(options={"agent_pos": [[0.0, 0.0], [0.5, 0.0]], "landmark_pos": [[0.5, 0.0], [-0.6, 0.6]],
                     "keep": [True, False]})
    assert w.covered.tolist() == [[True, False]]
    _, info = act(w, [0, 0])                         # agent 1 leaves after step 1
    assert info["alive"].tolist() == [[True, False]] and info["covered"].tolist() == [[False, False]]
    assert info["reached"].tolist() == [[True, False]]  # ever reached stays
    place(w, [[0.45, 0.05], [0.5, 0.0]])             # alive agent right on top of the dropped one
    _, info = act(w, [0, 0])
    assert float(w.agent_vel.abs().max()) < 1e-12  # an overlap with an alive agent would give ~1 m/s
    assert info["collisions"].tolist() == [0] and info["agent_collisions"].tolist() == [[0, 0]]


# ------------------------------------------------------------------ determinism
def rollout(seed, name="mpe-20to10", steps=30):
    w = make(name, num_envs=3, seed=seed)
    gen = torch.Generator().manual_seed(seed)
    traj = [w.agent_pos.clone()]
    for _ in range(steps):
        w.step(torch.randint(0, 5, (3, w.num_agents), generator=gen))
        traj.append(torch.cat([w.agent_pos.flatten(), w.alive.flatten().float()]))
    w.reset()
    traj.append(w.landmark_pos.clone())
    return traj


def test_same_seed_same_trajectory_and_different_seeds_differ():
    a, b, c = rollout(7), rollout(7), rollout(8)
    assert all(torch.equal(x, y) for x, y in zip(a, b))
    assert not torch.equal(a[0], c[0]) and not torch.equal(a[-1], c[-1])


def test_reset_seed_restarts_the_same_episode():
    w = make("mpe-20", num_envs=2, seed=0)
    first = w.reset(seed=11)["agent_pos"].clone()
    w.reset()
    assert torch.equal(w.reset(seed=11)["agent_pos"], first)


def test_presets_have_the_paper_sizes():
    sizes = {n: (s.num_agents, s.num_obstacles, round(s.area), s.horizon) for n, s in SCENARIOS.items()}
    assert sizes["mpe-5"] == (5, 5, 4, 18) and sizes["mpe-20"] == (20, 10, 64, 45)
    assert sizes["mpe-50"] == (50, 30, 400, 90)


def test_unseeded_world_leaves_the_global_torch_generator_alone():
    torch.manual_seed(0)
    expected = torch.rand(3)
    torch.manual_seed(0)
    make("mpe-5")
    assert torch.equal(torch.rand(3), expected)


def test_set_state_branches_an_episode_mid_way_and_steps_as_the_original():
    import pytest
    w = make("mpe-20to10", num_envs=2, seed=3)
    w.reset()
    g = torch.Generator().manual_seed(0)
    for _ in range(16):  # past the team change
        w.step(torch.randint(0, 5, (2, 20), generator=g))
    copies = make("mpe-20to10", num_envs=6, seed=9)
    obs = copies.set_state(w.get_state(), repeat=3)
    assert torch.equal(obs["agent_pos"][3], w.agent_pos[1]) and torch.equal(obs["alive"][:3], w.alive[[0, 0, 0]])
    a = torch.randint(0, 5, (2, 20), generator=g)
    ref_obs, ref_info = w.step(a)
    obs, info = copies.step(a.repeat_interleave(3, dim=0))
    assert torch.equal(obs["agent_pos"][::3], ref_obs["agent_pos"])
    assert torch.equal(info["collisions"][::3], ref_info["collisions"]) and torch.equal(obs["t"][::3], ref_obs["t"])
    with pytest.raises(ValueError, match="repeat"):
        copies.set_state(w.get_state(), repeat=4)
    with pytest.raises(ValueError, match="keys"):
        copies.set_state({"agent_pos": w.agent_pos})
    with pytest.raises(ValueError, match="agent_pos"):
        copies.set_state({**w.get_state(), "agent_pos": torch.zeros(2, 5, 2)}, repeat=3)


def test_central_landmark_spawn_keeps_landmarks_in_the_central_square_and_agents_everywhere():
    L = make("mpe-20").scenario.world_size
    w = make("mpe-20", num_envs=300, seed=0)  # the preset: the paper's world
    assert w.scenario.landmark_spawn == "central"
    assert float(w.landmark_pos.abs().max()) <= 0.8 * L / 2
    assert float(w.agent_pos.abs().max()) > 0.9 * L / 2          # agents still use the whole map
    whole = make("mpe-20", num_envs=300, seed=0, landmark_spawn="whole")
    assert float(whole.landmark_pos.abs().max()) > 0.9 * L / 2
    with pytest.raises(ValueError, match="landmark_spawn"):
        make("mpe-20", landmark_spawn="middle")
    with pytest.raises(ValueError, match="landmark_spawn"):
        make("drone-5", landmark_spawn="central")
