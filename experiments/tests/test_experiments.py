"""The research scripts in experiments/ agree with the world's dynamics (findings: docs/research-log.md)."""
import numpy as np
import pytest
import torch

from experiments import mpe5_distill, mpe5_failures, mpe5_oracle
from masp_lite.algos.assignment import hungarian
from masp_lite.envs import MPE2_WORLD, make
from masp_lite.weights import load_weights


@pytest.fixture(scope="module")
def failures():
    return mpe5_failures


@pytest.fixture(scope="module")
def oracle():
    return mpe5_oracle


def _push_x(steps):
    """x of one agent from rest at the origin after ``steps`` steps of the +x action, in mpe2's order (the
    world ``mpe5_failures`` models)."""
    w = make("mpe-5", num_envs=1, num_agents=1, num_obstacles=0, seed=0, **MPE2_WORLD)
    w.reset(options={"agent_pos": torch.zeros(1, 2), "landmark_pos": torch.tensor([[0.9, 0.9]])})
    for _ in range(steps):
        w.step(torch.tensor([[2]]))
    return float(w.agent_pos[0, 0, 0])


@pytest.mark.parametrize("T", [1, 4, 9])
def test_push_front_matches_the_world(failures, T):
    FX, FY = failures.push_front(T)
    assert FX.max() == pytest.approx(_push_x(T), abs=1e-5)   # all pushes along x
    assert FY.min() == pytest.approx(0.0, abs=1e-12)
    assert np.all(np.diff(FX) < 0) and np.all(np.diff(FY) > 0)  # a Pareto front


def test_t_star_is_the_first_covering_step_on_a_straight_line(failures):
    """Pushing straight at a landmark on the x axis is optimal: T* is when the world first covers it."""
    reach = 0.15
    for dist in (0.3, 0.8, 1.6):
        t_world = next(t for t in range(1, 19) if _push_x(t) >= dist - reach)
        agents, lms = np.zeros((1, 1, 2)), np.array([[[dist, 0.0]]])
        assert failures.t_star(agents, lms, reach, 18)[0] == t_world
    assert failures.t_star(np.zeros((1, 1, 2)), np.array([[[5.0, 0.0]]]), reach, 18)[0] == 19  # out of reach


def test_t_star_lets_one_agent_cover_two_close_landmarks(failures):
    agents = np.array([[[0.0, 0.0], [3.0, 3.0]]])            # the second agent is far from both
    close = np.array([[[0.5, 0.0], [0.5, 0.25]]])            # 0.25 m apart: one agent covers both
    apart = np.array([[[0.5, 0.0], [0.5, 0.4]]])             # 0.4 m apart: it cannot
    assert failures.t_star(agents, close, 0.15, 18)[0] < 19
    assert failures.t_star(agents, apart, 0.15, 18)[0] > failures.t_star(agents, close, 0.15, 18)[0]


@pytest.mark.parametrize("obstacle_y, expected", [(0.05, True), (0.5, False)])
def test_blocked_sees_an_obstacle_across_the_straight_line(failures, obstacle_y, expected):
    w = make("mpe-5", num_envs=1, num_agents=1, num_obstacles=1, seed=0)
    w.reset(options={"agent_pos": torch.tensor([[-0.8, 0.0]]), "landmark_pos": torch.tensor([[0.8, 0.0]]),
                     "obstacle_pos": torch.tensor([[0.0, obstacle_y]])})
    assert failures.blocked(w, 0, 0, torch.tensor([[0]])) is expected


def test_landmark_geometry_nearest_landmark_and_obstacle(failures):
    landmarks = torch.tensor([[[0.0, 0.0], [0.2, 0.0], [1.0, 0.0]]])
    obstacles = torch.tensor([[[0.0, 0.5], [1.0, -0.3]]])
    near_lm, near_obst = failures.landmark_geometry(landmarks, obstacles)
    assert near_lm[0].tolist() == pytest.approx([0.2, 0.2, 0.8])
    assert near_obst[0].tolist() == pytest.approx([0.5, (0.2 ** 2 + 0.5 ** 2) ** 0.5, 0.3])
    _, none = failures.landmark_geometry(landmarks, obstacles[:, :0])
    assert torch.isinf(none).all()


def test_arrival_controller_brings_one_agent_to_rest_on_its_landmark(oracle):
    w = make("mpe-5", num_envs=1, num_agents=1, num_obstacles=0, seed=0)
    goal = torch.tensor([[[0.7, -0.4]]], dtype=w.agent_pos.dtype)
    w.reset(options={"agent_pos": torch.tensor([[-0.6, 0.5]]), "landmark_pos": goal[0]})
    for _ in range(w.horizon):
        w.step(oracle.arrival_actions(w.agent_pos, w.agent_vel, goal))
    assert float((w.agent_pos - goal).norm()) < w.scenario.reach_distance
    assert float(w.agent_vel.norm()) < 0.6


def test_copy_state_makes_copies_that_step_like_the_world(oracle):
    w = make("mpe-5", num_envs=2, seed=3)
    w.reset(seed=3)
    gen = torch.Generator().manual_seed(0)
    for _ in range(4):                                     # mid-episode, with velocities
        w.step(torch.randint(0, 5, (2, 5), generator=gen))
    sim = make("mpe-5", num_envs=6, seed=0)
    sim.reset(seed=0)
    oracle.copy_state(sim, w, 3)
    a = torch.randint(0, 5, (2, 5), generator=gen)
    w.step(a)
    sim.step(a.repeat_interleave(3, 0))
    torch.testing.assert_close(sim.agent_pos, w.agent_pos.repeat_interleave(3, 0))
    assert torch.equal(sim.t, w.t.repeat_interleave(3, 0))


def test_search_oracle_with_one_noise_free_copy_is_the_arrival_controller(oracle):
    w = make("mpe-5", num_envs=3, seed=1)
    obs = w.reset(seed=1)
    o = oracle.SearchOracle(w, candidates=1, noise=0.0)
    goals = hungarian(w.agent_pos, w.landmark_pos, w.alive, None, 2.0)
    goal_pos = torch.gather(w.landmark_pos, 1, goals.unsqueeze(-1).expand(3, 5, 2))
    controller = oracle.arrival_actions(w.agent_pos, w.agent_vel, goal_pos)
    assert torch.equal(o.act(obs), controller)
    assert torch.equal(oracle.SearchOracle(w, candidates=1, noise=0.0, per_agent=True).act(obs), controller)
    assert int(w.t.max()) == 0                              # searching does not move the world


def test_per_agent_search_only_perturbs_the_searching_agent(oracle):
    w = make("mpe-5", num_envs=2, seed=4)
    obs = w.reset(seed=4)
    o = oracle.SearchOracle(w, candidates=8, noise=1.0, per_agent=True)
    captured = {}
    step = o.sim.step

    def spy(a):
        captured.setdefault("first", a.clone())
        return step(a)
    o.sim.step = spy
    o.act(obs)
    moves = captured["first"].view(2, 5, 8, 5)                # (world, searching agent, copy, agent)
    goals = hungarian(w.agent_pos, w.landmark_pos, w.alive, None, 2.0)
    goal_pos = torch.gather(w.landmark_pos, 1, goals.unsqueeze(-1).expand(2, 5, 2))
    controller = oracle.arrival_actions(w.agent_pos, w.agent_vel, goal_pos)
    for k in range(5):
        others = [j for j in range(5) if j != k]
        assert torch.equal(moves[:, k, :, others], controller[:, None, others].expand(2, 8, 4))
    assert not torch.equal(moves[:, :, -1].diagonal(dim1=1, dim2=2), controller)   # the noisiest copies deviate


@pytest.fixture(scope="module")
def distill():
    return mpe5_distill


def test_action_search_keeps_the_controller_unless_another_action_wins_by_the_margin(oracle, distill):
    w = make("mpe-5", num_envs=3, seed=2)
    obs = w.reset(seed=2)
    goals = torch.arange(5).expand(3, 5).clone()
    goal_pos = torch.gather(w.landmark_pos, 1, goals.unsqueeze(-1).expand(3, 5, 2))
    controller = oracle.arrival_actions(w.agent_pos, w.agent_vel, goal_pos)
    s = distill.ActionSearch(w, copies=4, margin=1e9)
    s.given = goals
    assert torch.equal(s.act(obs), controller)
    captured = {}
    s = distill.ActionSearch(w, copies=4, margin=0.0)
    s.given = goals
    step = s.sim.step

    def spy(a):
        captured.setdefault("first", a.clone())
        return step(a)
    s.sim.step = spy
    label = s.act(obs)
    first = captured["first"].view(3, 5, 5, 4, 5)              # (world, agent k, forced action, copy, agent)
    for k in range(5):
        assert torch.equal(first[:, k, :, :, k], torch.arange(5).view(1, 5, 1).expand(3, 5, 4))
        others = [j for j in range(5) if j != k]
        assert torch.equal(first[:, k, :, :, others], controller[:, None, None, others].expand(3, 5, 4, 4))
    assert label.shape == (3, 5) and int(w.t.max()) == 0


def test_collect_labels_every_visited_state_and_fit_learns_the_labels(distill):
    nets, _ = load_weights(None, scenario=make("mpe-5", num_envs=1).scenario)
    data = distill.collect(nets, seed=1000, beta=1.0, candidates=5, kind="action", weights={}, episodes=4)
    assert data["action"].shape == (4 * 18, 5) and data["goals"].shape == (4 * 18, 5)
    assert set(data) == {*distill.KEYS, "goals", "action"}
    assert distill.state_features(data).shape[:2] == (4 * 18, 5)
    data["action"] = torch.full_like(data["action"], 3)         # a label the executor can learn
    before = distill.fit(nets, data, epochs=1, lr=0.0, seed=0)
    after = distill.fit(nets, data, epochs=40, lr=3e-3, seed=0)
    assert after < 0.5 * before


def test_near_miss_prices_closing_passes_inside_the_zone_only():
    from experiments.drone_nearmiss import near_miss
    from masp_lite.envs.drone_model import COLLISION_RADIUS
    alive = torch.ones(1, 3, dtype=torch.bool)
    pos = torch.tensor([[[0.0, 0.0, 1.0], [0.8, 0.0, 1.0], [5.0, 5.0, 1.0]]])
    towards = torch.tensor([[[3.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]])
    p = near_miss(pos, towards, alive, zone=1.5)
    d_c = 2 * COLLISION_RADIUS
    expected = 1 - (0.8 - d_c) / (1.5 - d_c)                     # full closing speed (3 m/s = V)
    assert torch.allclose(p, torch.tensor([[expected, expected, 0.0]]))
    assert torch.equal(near_miss(pos, -towards, alive, zone=1.5), torch.zeros(1, 3))   # separating: free
    assert torch.equal(near_miss(pos, towards, alive, zone=0.7), torch.zeros(1, 3))    # outside the zone
    gone = torch.tensor([[True, False, True]])
    assert torch.equal(near_miss(pos, towards, gone, zone=1.5), torch.zeros(1, 3))     # a crashed drone is no one


def test_crash_rows_describe_the_pair_at_the_step_before():
    from experiments.drone_crashes import crash_rows
    pos = torch.tensor([[[0.0, 0.0, 1.0], [0.5, 0.0, 1.2], [4.0, 4.0, 1.0]]])
    vel = torch.tensor([[[2.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]])
    prev = {"agent_pos": pos, "agent_vel": vel, "alive": torch.ones(1, 3, dtype=torch.bool)}
    now = {"alive": torch.tensor([[False, False, True]])}
    rows = crash_rows(prev, now, keep=1)
    assert [(r["drone"], r["other"], r["both"]) for r in rows] == [(0, 1, True), (1, 0, True)]
    assert rows[0]["horizontal"] == pytest.approx(0.5) and rows[0]["vertical"] == pytest.approx(0.2)
    assert rows[0]["closing"] == pytest.approx(2.0 * 0.5 / np.hypot(0.5, 0.2))
    assert crash_rows(prev, now, keep=0) == []                     # worlds past keep do not count


def test_a_collision_radius_builds_larger_spheres_and_names_its_world():
    """drone_margin's training world: the scenario override ``collision_radius`` (what ``--radius`` sets)."""
    import mujoco

    from masp_lite.envs.drone_model import COLLISION_RADIUS

    def hull(world):
        return float(world.model.geom_size[mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_GEOM, "d0_hull"), 0])
    wide = make("drone-5", num_envs=1, seed=0, collision_radius=0.37)
    assert hull(wide) == pytest.approx(0.37) and wide.scenario.world == {"collision_radius": 0.37}
    true = make("drone-5", num_envs=1, seed=0)
    assert hull(true) == pytest.approx(COLLISION_RADIUS) and true.scenario.world == {}


@pytest.mark.parametrize("frame, crashed", [(False, True), (True, False)])
def test_flat_frames_let_drones_pass_where_the_spheres_touch(frame, crashed):
    """Two hovering drones 0.5 m apart across and 0.12 m in height: 0.514 m between centres, inside the spheres'
    contact distance (0.54 m) but clear of two 6 cm-tall frames."""
    from experiments.drone_frame import FrameWorld
    from masp_lite.envs.drone_model import HOVER_COMMAND
    from masp_lite.envs.drones import DroneWorld

    w = (FrameWorld if frame else DroneWorld)("drone-5", num_envs=1, num_agents=2, seed=0)
    pos = torch.tensor([[[0.0, 0.0, 1.5], [0.5, 0.0, 1.62]]], dtype=torch.float64)
    w.reset(options={"agent_pos": pos})
    w.step(torch.full((1, 2, 4), HOVER_COMMAND))
    assert bool((~w.alive).any()) == crashed


def test_contact_nets_add_two_pair_features_and_are_built_in_the_products_order():
    from experiments.drone_contact import ContactNets
    from masp_lite.nets.drones import DroneNets

    torch.manual_seed(0)
    product = DroneNets(action="velocity").state_dict()
    torch.manual_seed(0)
    contact = ContactNets(action="velocity").state_dict()
    assert contact["cae.fusion.embed.0.weight"].shape[1] == product["cae.fusion.embed.0.weight"].shape[1] + 2
    assert sorted(contact) == sorted(product)
    assert all(torch.equal(v, product[k]) for k, v in contact.items() if k.startswith("gm"))  # built first
    w = make("drone-5", num_envs=2, seed=0)
    obs = w.reset()
    goals, perm = torch.zeros(2, 5, dtype=torch.long), torch.arange(5).expand(2, 5)
    pair = ContactNets(action="velocity").cae_inputs(obs, goals, perm)[0]
    assert pair.shape == (2, 5, 5, 10)
    assert torch.equal(pair[..., :8], DroneNets(action="velocity").cae_inputs(obs, goals, perm)[0])


def test_mpe50_goals_drives_the_executor_to_the_reference_goals():
    from experiments import mpe50_goals
    w = make("mpe-20", num_envs=3, seed=100)
    obs = w.reset(seed=100)
    pol = mpe50_goals.ReferenceGoals(w, "masp_lite/weights/mpe-20.pt", "squared", seed=100)
    pol.reset(obs)
    actions = pol.act(obs)
    assert actions.shape == (3, 20) and actions.dtype == torch.long
    want = hungarian(obs["agent_pos"], obs["landmark_pos"], obs["alive"], None, 2.0)
    assert torch.equal(pol.goals, want)
    assert not torch.equal(want, hungarian(obs["agent_pos"], obs["landmark_pos"], obs["alive"], None, 1.0))


def test_mpe50_goals_agreement_is_a_fraction_per_reference():
    from experiments import mpe50_goals
    rows = mpe50_goals.measure("mpe-5", "masp_lite/weights/mpe-5.pt", [100], 2)
    assert set(rows) == {"own", "distance", "squared", "bottleneck"}
    agree = rows["own"][1]
    assert set(agree) == set(mpe50_goals.REFERENCES) and all(0.0 < v <= 1.0 for v in agree.values())
    assert all(1 <= rows[k][0] <= 25 for k in rows)  # Steps within mpe-5's horizon


def test_minmax_assignment_minimises_the_longest_cost_then_the_sum():
    import itertools

    import numpy as np

    from experiments.mpe50_decode import minmax_assignment
    rng = np.random.default_rng(0)
    for _ in range(20):
        d = rng.random((4, 4))
        r, c = minmax_assignment(d)
        perms = list(itertools.permutations(range(4)))
        best = min(perms, key=lambda p: (max(d[k, p[k]] for k in range(4)), sum(d[k, p[k]] for k in range(4))))
        assert list(c[np.argsort(r)]) == list(best)


def test_perturbed_joint_sample_draws_distinct_goals_with_unrestricted_log_probabilities():
    from experiments.mpe50_joint_draw import perturbed_joint_sample
    logits = torch.randn(3, 5, 5)
    alive = torch.ones(3, 5, dtype=torch.bool)
    goals, logp, rank = perturbed_joint_sample(logits, alive, torch.Generator().manual_seed(0))
    assert all(len(set(g.tolist())) == 5 for g in goals) and not rank.any()
    assert torch.allclose(logp, torch.log_softmax(logits, -1).gather(-1, goals.unsqueeze(-1)).squeeze(-1))


def test_remake_records_selects_by_method_and_scenario_and_rebuilds_a_record_as_made():
    from experiments import remake_records
    from masp_lite.reproduction.reproduce import re_evaluate
    found = remake_records.records(["gm-mlp"], ["mpe-20"])
    assert found and all(r["method"] == "gm-mlp" and r["scenario"] == "mpe-20" for _, r in found)
    path, rec = next((p, r) for p, r in remake_records.records(["h-greedy"], ["mpe-5"]) if "overrides" not in r)
    rec = {**rec, "seeds": rec["seeds"][:1], "episodes_per_seed": 2}
    new = re_evaluate(rec)
    assert "overrides" not in new and new["world"] == rec["world"] and new["seeds"] == rec["seeds"]


def test_experiment_trainers_change_their_part_without_touching_the_library():
    """drone_sense's networks clip at ``--sense`` (the product's still at 2 m); mpe50_joint_draw's trainer draws
    perturb-and-MAP goals; both are subclasses passed to ``train``, not patches."""
    from experiments.drone_sense import sense_trainer
    from experiments.mpe50_joint_draw import PerturbedDrawTrainer, perturbed_joint_sample
    from masp_lite.algos.masp_trainer import MASPTrainer
    from masp_lite.config import NetConfig
    from masp_lite.nets.drones import DroneNets
    from masp_lite.nets.goal_draw import sequential_sample
    obs = {"agent_pos": torch.tensor([[[0.0, 0.0, 1.5], [3.0, 0.0, 1.5]]]), "agent_vel": torch.zeros(1, 2, 3),
           "landmark_pos": torch.zeros(1, 2, 3), "alive": torch.ones(1, 2, dtype=torch.bool),
           "agent_quat": torch.tensor([[[1.0, 0, 0, 0]] * 2]), "agent_angvel": torch.zeros(1, 2, 3),
           "throttle": torch.zeros(1, 2, 4)}
    goals, perm = torch.zeros(1, 2, dtype=torch.long), torch.arange(2)[None]
    seen = [nets(NetConfig(action="throttle")).cae_inputs(obs, goals, perm)[0][0, 0, 1, 3].item()
            for nets in (DroneNets, sense_trainer(4.0).nets_class)]
    assert seen == pytest.approx([1.0, 0.75])  # min(d, sense) / sense of a drone 3 m away
    assert DroneNets.sense == 2.0
    assert PerturbedDrawTrainer.draw_goals is perturbed_joint_sample and MASPTrainer.draw_goals is sequential_sample
