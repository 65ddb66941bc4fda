"""Planning baselines: ORCA, RRT*, Voronoi, the shared controller and the (H) policies."""
import numpy as np
import pytest
import torch

from masp_lite.envs import make
from masp_lite.planners.controllers import arrive_velocity, next_velocities, track_path, velocity_to_action
from masp_lite.planners.orca import orca_halfplanes, orca_velocities, solve_orca
from masp_lite.planners.rrt_star import plan_rrt_star, rewire, segment_hits
from masp_lite.planners.voronoi import plan_voronoi
from masp_lite.policies import make_policy
from masp_lite.policies.planners import HOrca, HRRTStar, HungarianPlanner, HVoronoi, split_collisions

RA, RO = 0.1, 0.1


# ----------------------------------------------------------------------------- controller
def test_controller_picks_the_best_next_velocity():
    rng = np.random.default_rng(0)
    vel, want = rng.normal(size=(200, 2)), rng.normal(size=(200, 2))
    act = velocity_to_action(vel, want)
    err = np.linalg.norm(next_velocities(vel) - want[:, None], axis=-1)
    assert np.allclose(err[np.arange(200), act], err.min(1))
    t = velocity_to_action(torch.tensor(vel), torch.tensor(want))
    assert t.dtype == torch.long and t.tolist() == act.tolist()


def test_controller_matches_the_reference_controller():
    from masp_lite.policies import reference as ref
    g = torch.Generator().manual_seed(1)
    vel, want = torch.randn(500, 2, generator=g), torch.randn(500, 2, generator=g) * 2
    assert torch.equal(velocity_to_action(vel, want), ref.velocity_to_action(vel, want))


def test_controller_rejects_bad_shapes():
    with pytest.raises(ValueError, match="same shape"):
        velocity_to_action(np.zeros((3, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        arrive_velocity(np.zeros(3), np.zeros(3))


def test_track_path_switches_waypoints_and_arrives():
    wp = np.array([[[1.0, 0.0], [1.0, 1.0], [1.0, 1.0]]])
    v, idx = track_path(np.array([[0.9, 0.0]]), wp, np.array([0]))
    assert idx[0] == 1 and v[0, 1] > 0 and abs(v[0, 0]) < 0.5   # heads up to the goal
    v, idx = track_path(np.array([[1.0, 1.0]]), wp, np.array([1]))
    assert np.allclose(v, 0)                                        # on the goal: stand still


# ----------------------------------------------------------------------------------- ORCA
def test_orca_halfplanes_are_reciprocal():
    """ORCA_A|B and ORCA_B|A: opposite directions, and each agent takes half of u."""
    pa, pb, va, vb = np.array([0.0, 0.0]), np.array([1.0, 0.1]), np.array([1.0, 0.0]), np.array([-1.0, 0.0])
    pt_a, d_a = orca_halfplanes(pb - pa, va - vb, va, 0.3, 0.5, 2.0, 0.1)
    pt_b, d_b = orca_halfplanes(pa - pb, vb - va, vb, 0.3, 0.5, 2.0, 0.1)
    assert np.allclose(d_a, -d_b)
    assert np.allclose(pt_a - va, -(pt_b - vb))
    # the current (colliding) velocities violate both half-planes
    det = lambda d, p: d[0] * p[1] - d[1] * p[0]  # noqa: E731
    assert det(d_a, pt_a - va) > 0 and det(d_b, pt_b - vb) > 0


def test_lp_projects_onto_a_single_halfplane_and_survives_infeasibility():
    # one constraint: x <= 0.2 (direction +y, permitted side on the left)
    P, D = np.array([[[0.2, 0.0]]]), np.array([[[0.0, 1.0]]])
    v = solve_orca(P, D, np.ones((1, 1), bool), np.array([[1.0, 0.5]]), 2.0)
    assert np.allclose(v, [[0.2, 0.5]])
    # contradictory constraints x <= -0.5 and x >= 0.5: the fallback balances the violation
    P = np.array([[[-0.5, 0.0], [0.5, 0.0]]])
    D = np.array([[[0.0, 1.0], [0.0, -1.0]]])
    v = solve_orca(P, D, np.ones((1, 2), bool), np.array([[1.0, 0.0]]), 2.0)
    assert np.isfinite(v).all() and abs(v[0, 0]) < 1e-6 and np.linalg.norm(v) <= 2.0 + 1e-9
    with pytest.raises(ValueError, match="pref_vel"):
        solve_orca(P, D, np.ones((1, 2), bool), np.zeros((2, 2)), 2.0)


class _Fixed(HungarianPlanner):
    """Test helper: agent i goes to landmark i (no assignment), straight like h-greedy."""

    def assign(self, obs):
        return np.tile(np.arange(obs["agent_pos"].shape[1]), (obs["agent_pos"].shape[0], 1))

    def desired_velocity(self, obs, goals, due):
        return arrive_velocity(obs["agent_pos"].numpy(), goals)


class _FixedOrca(_Fixed, HOrca):
    desired_velocity = HOrca.desired_velocity


def _episode(policy_cls, options, scenario="mpe-5", steps=None, **overrides):
    w = make(scenario, num_envs=1, seed=0, **overrides)
    obs = w.reset(options=options)
    pol = policy_cls(w)
    pol.reset(obs)
    hits, split = 0, [0, 0]
    for _ in range(steps or w.horizon):
        obs, info = w.step(pol.act(obs))
        hits += int(info["collisions"].sum())
        aa, ao = split_collisions(obs, w.scenario)
        assert int(aa.sum() + ao.sum()) == int(info["collisions"].sum())
        split[0] += int(aa.sum())
        split[1] += int(ao.sum())
    return obs, hits, split


def test_orca_keeps_a_head_on_swap_apart_where_straight_lines_collide():
    opts = {"agent_pos": [[-1.0, 0.0], [1.0, 0.0]], "landmark_pos": [[1.0, 0.0], [-1.0, 0.0]]}
    kw = dict(num_agents=2, num_obstacles=0, horizon=40)
    obs, greedy_hits, _ = _episode(_Fixed, opts, **kw)
    assert greedy_hits > 0
    obs, orca_hits, _ = _episode(_FixedOrca, opts, **kw)
    assert orca_hits == 0
    assert bool(obs["covered"].all())               # and both still arrive


def test_orca_velocities_respect_the_speed_bound_and_dead_agents():
    rng = np.random.default_rng(3)
    pos, vel = rng.uniform(-2, 2, (2, 12, 2)), rng.normal(size=(2, 12, 2))
    alive = np.ones((2, 12), bool)
    alive[1, :4] = False
    out = orca_velocities(pos, vel, rng.normal(size=(2, 12, 2)) * 3, rng.uniform(-2, 2, (2, 3, 2)),
                          agent_radius=RA, obstacle_radius=RO, alive=alive, max_speed=1.5)
    assert np.linalg.norm(out, axis=-1).max() <= 1.5 + 1e-6
    assert np.allclose(out[1, :4], 0)


# ------------------------------------------------------------------------- RRT*, Voronoi
WALL = np.array([[0.0, y] for y in np.arange(-1.2, 1.21, 0.2)])      # a vertical wall of circles


def _clear(points, obstacles, radius):
    """Minimum distance from a polyline to the obstacle centres minus ``radius``."""
    seg = np.stack([points[:-1], points[1:]], 1)
    worst = np.inf
    for a, b in seg:
        d = b - a
        t = np.clip(((obstacles - a) @ d) / max(d @ d, 1e-12), 0, 1)
        worst = min(worst, (np.linalg.norm(a + t[:, None] * d - obstacles, axis=1) - radius).min())
    return worst


def test_rrt_star_paths_go_around_the_wall():
    start, goal = np.array([[[-1.5, 0.0], [-1.5, 0.5]]]), np.array([[[1.5, 0.0], [1.5, -0.4]]])
    radii = np.full(len(WALL), RA + RO + 0.05)
    paths = plan_rrt_star(start, goal, WALL[None], radii, np.ones((1, len(WALL)), bool), np.ones((1, 2), bool),
                          np.random.default_rng(0), bounds=3.0, samples=80)
    for n in range(2):
        pts = np.concatenate([start[0, n][None], paths[0, n]])
        assert np.allclose(pts[-1], goal[0, n])
        assert _clear(pts, WALL, RA + RO) > 0                      # never touches the wall
        assert np.linalg.norm(np.diff(pts, axis=0), axis=1).sum() < 6.0  # and is not a detour


def test_rrt_star_goes_straight_when_free_and_is_reproducible():
    start, goal = np.array([[[-1.5, 1.8]]]), np.array([[[1.5, 1.8]]])
    args = (WALL[None], np.full(len(WALL), 0.25), np.ones((1, len(WALL)), bool), np.ones((1, 1), bool))
    assert np.allclose(plan_rrt_star(start, goal, *args, np.random.default_rng(0))[0, 0], goal[0])
    s2, g2 = np.array([[[-1.5, 0.1]]]), np.array([[[1.5, -0.1]]])
    a = plan_rrt_star(s2, g2, *args, np.random.default_rng(5), bounds=2.0)
    b = plan_rrt_star(s2, g2, *args, np.random.default_rng(5), bounds=2.0)
    assert np.array_equal(a, b)


def test_rewire_step_reparents_through_a_cheaper_new_node():
    # root 0 at origin; node 1 reached by a detour (cost 5); new node 2 sits between them
    nodes = np.array([[[0.0, 0.0], [2.0, 0.0], [1.0, 0.0]]])
    cost = np.array([[0.0, 5.0, 1.0]])
    parent = np.array([[-1, 0, 0]])
    better = rewire(nodes, cost, parent, np.array([2]), np.array([[0, 1]]), np.array([[True, True]]))
    assert better.tolist() == [[False, True]]
    assert parent[0, 1] == 2 and np.isclose(cost[0, 1], 2.0) and parent[0, 0] == -1
    parent2, cost2 = np.array([[-1, 0, 0]]), np.array([[0.0, 5.0, 1.0]])
    rewire(nodes, cost2, parent2, np.array([2]), np.array([[0, 1]]), np.array([[True, False]]))
    assert parent2[0, 1] == 0                                  # a blocked edge never rewires


def test_segment_hits():
    hits = segment_hits(np.array([-1.0, 0.0]), np.array([1.0, 0.0]), np.array([[0.0, 0.1], [0.0, 0.5]]), 0.2)
    assert hits.tolist() == [True, False]


def test_voronoi_paths_go_around_the_wall():
    pos = np.array([[[-1.5, 0.0], [-1.5, 0.6], [1.0, 1.8]]])
    goals = np.array([[[1.5, 0.0], [1.5, -0.5], [1.0, 1.8]]])
    paths = plan_voronoi(pos, goals, WALL[None], np.ones((1, 3), bool), agent_radius=RA,
                         obstacle_radius=RO, half_size=2.0)
    for n in range(3):
        pts = np.concatenate([pos[0, n][None], paths[0, n]])
        assert np.allclose(pts[-1], goals[0, n])
        assert _clear(pts, WALL, RA + RO) > 0
    assert np.allclose(paths[0, 2], goals[0, 2])                 # already there: stays


# ------------------------------------------------------------------------------ policies
SMALL = {"agent_pos": [[-1.6, -0.5], [-1.6, 0.5], [-1.6, 1.5]],
         "landmark_pos": [[1.5, -0.4], [1.5, 0.6], [1.5, 1.4]],
         "obstacle_pos": [[0.0, -0.45], [0.0, 0.55], [0.0, 1.45]]}   # one on each straight line


@pytest.mark.parametrize("name", ["h-orca", "h-rrtstar", "h-voronoi"])
def test_each_planner_solves_a_small_fixed_scenario(name):
    w = make("mpe-5", num_envs=1, seed=0, num_agents=3, num_obstacles=3, horizon=40, world_size=4.0)
    obs = w.reset(options=SMALL)
    pol = make_policy(name, w)
    pol.reset(obs)
    obstacle_hits = 0
    for _ in range(w.horizon):
        obs, info = w.step(pol.act(obs))
        obstacle_hits += int(split_collisions(obs, w.scenario)[1].sum())
    assert bool(obs["covered"].all()), name
    assert obstacle_hits == 0, name


def test_same_seed_same_actions():
    runs = []
    for _ in range(2):
        w = make("mpe-20", num_envs=2, seed=3)
        obs = w.reset()
        pol = HRRTStar(w, seed=1)
        pol.reset(obs)
        acts = []
        for _ in range(6):
            a = pol.act(obs)
            acts.append(a)
            obs, _ = w.step(a)
        runs.append(torch.stack(acts))
    assert torch.equal(*runs)


def test_varying_team_assigns_a_random_subset_of_unreached_landmarks():
    w = make("mpe-20to10", num_envs=4, seed=0, num_agents=6, team_after=2, change_step=1)
    obs = w.reset()
    obs, _ = w.step(torch.zeros(4, 6, dtype=torch.long))   # after step 1 only 2 agents remain
    subsets = set()
    for seed in range(6):
        pol = HVoronoi(w, seed=seed)
        pol.reset(obs)
        idx = pol.assign(obs)
        for b in range(4):
            alive, unreached = obs["alive"][b].numpy(), ~obs["reached"][b].numpy()
            got = idx[b][alive]
            assert (idx[b][~alive] == -1).all()
            assert len(set(got.tolist())) == alive.sum() == 2       # one distinct goal each
            assert unreached[got].all()                             # only unreached landmarks
            subsets.add((seed, b, tuple(sorted(got.tolist()))))
    per_b = {b: {s for (_, bb, s) in subsets if bb == b} for b in range(4)}
    assert any(len(v) > 1 for v in per_b.values())                  # the subset is random...
    again = HVoronoi(w, seed=0)
    again.reset(obs)
    first = HVoronoi(w, seed=0)
    first.reset(obs)
    assert np.array_equal(again.assign(obs), first.assign(obs))     # ...and seeded


def test_policies_reject_unknown_options_and_drone_worlds():
    w = make("mpe-5", num_envs=1, seed=0)
    with pytest.raises(ValueError, match="unknown option"):
        HOrca(w, horizon_typo=3)
    with pytest.raises(ValueError, match="unknown option"):
        HVoronoi(w, samples=3)


def test_goals_next_to_obstacles_move_clear_but_stay_in_reach():
    w = make("mpe-5", num_envs=1, seed=0)
    pol = HOrca(w)
    obstacles = np.array([[[0.0, 0.0], [1.0, 1.0]]])
    goals = np.array([[[0.17, 0.0], [0.0, 0.5], [1.0, 1.3]]])
    out = pol.standoff(goals, obstacles)
    assert np.linalg.norm(out[0, 0]) >= w.scenario.agent_radius + w.scenario.obstacle_radius
    assert np.linalg.norm(out[0, 0] - goals[0, 0]) < w.scenario.reach_distance
    assert np.allclose(out[0, 1:], goals[0, 1:])                   # far enough already


def test_bench_planners_times_act_and_splits_collisions():
    from masp_lite.bench.planners import collision_split, step_times
    ms = step_times("h-orca", "mpe-5", episodes=1)
    assert ms.shape == (18,) and (ms > 0).all()
    s = collision_split("h-greedy", "mpe-5", episodes=8)
    assert np.isclose(s["cr"], s["agent_agent"] + s["agent_obstacle"]) and s["cr"] > 0
    with pytest.raises(ValueError, match="episodes"):
        step_times("h-orca", "mpe-5", episodes=0)


def test_bench_planners_times_the_drone_planners_without_the_papers_mpe_column(capsys):
    from masp_lite.cli import main
    assert main(["bench", "planners", "--scenario", "drone-5", "--methods", "h-orca", "--episodes", "1"]) == 0
    row = [line for line in capsys.readouterr().out.splitlines() if line.startswith("h-orca")][0]
    assert row.split()[3] == "-"            # no paper figure beside a drone timing


def test_voronoi_route_follows_predecessors():
    from masp_lite.planners.voronoi import route
    pred = np.array([-9999, 0, 1, 1, -9999])
    assert route(pred, 0, 3) == [0, 1, 3]
    assert route(pred, 0, 0) == [0]
    assert route(pred, 0, 4) == []
