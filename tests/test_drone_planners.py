"""The (H) planners on drones: registry dispatch, episodes flown, ORCA apart, paths around drones."""
import numpy as np
import pytest
import torch

from masp_lite import evaluation as ev
from masp_lite.envs import make
from masp_lite.envs.drone_model import COLLISION_RADIUS
from masp_lite.policies import drone_planners as dp
from masp_lite.policies import make_policy
from masp_lite.policies.drone_planners import DroneBottleneck, DroneHOrca, DroneHRRTStar, DroneHVoronoi, altitude_gap
from masp_lite.policies.planners import HOrca
from masp_lite.policies.reference import HungarianGreedy

DRONE_CLASSES = {"h-orca": DroneHOrca, "h-rrtstar": DroneHRRTStar, "h-voronoi": DroneHVoronoi,
                 "h-bottleneck": DroneBottleneck}


@pytest.mark.parametrize("name", sorted(DRONE_CLASSES))
def test_each_planner_flies_a_drone_5_episode(name):
    w = make("drone-5", num_envs=3, seed=0)
    policy = make_policy(name, w)
    assert type(policy) is DRONE_CLASSES[name]
    log, decision_s = ev.rollout(w, policy, episodes=3, seed=0)
    sr = float(ev.success_rate(log).mean())
    assert sr >= 0.9, f"{name}: SR {sr:.3f} on drone-5"
    assert decision_s > 0 and policy.assignment.shape == (3, 5)


def test_particle_worlds_keep_the_particle_classes():
    w = make("mpe-5", num_envs=1, seed=0)
    assert type(make_policy("h-orca", w)) is HOrca
    assert type(make_policy("h-bottleneck", w)) is HungarianGreedy


class _Swap:
    """Test helper: drone i goes to landmark i, whatever the distances."""

    def assign(self, obs):
        B, N = obs["alive"].shape
        return np.tile(np.arange(N), (B, 1))


class _SwapOrca(_Swap, DroneHOrca):
    pass


class _SwapStraight(_Swap, DroneBottleneck):
    pass


def _fly(cls, start, goals, horizon=250):
    """Two drones from ``start`` to ``goals`` (2, 3); returns (last obs, collisions, min distance, max |y|)."""
    w = make("drone-5", num_envs=1, seed=0, num_agents=2, horizon=horizon)
    obs = w.reset(options={"agent_pos": np.asarray(start), "landmark_pos": np.asarray(goals)})
    policy = cls(w)
    policy.reset(obs)
    hits, closest, side = 0, np.inf, 0.0
    for _ in range(w.horizon):
        obs, info = w.step(policy.act(obs))
        hits += int(info["collisions"].sum())
        p = obs["agent_pos"][0].double()
        closest = min(closest, float((p[0] - p[1]).norm()))
        side = max(side, float(p[:, 1].abs().max()))
    return obs, hits, closest, side


HEAD_ON = [[-2.0, 0.0, 1.5], [2.0, 0.0, 1.5]]


def test_orca_keeps_two_drones_on_a_head_on_course_apart():
    goals = [[2.0, 0.0, 1.5], [-2.0, 0.0, 1.5]]
    _, hits, _, _ = _fly(_SwapStraight, HEAD_ON, goals)
    assert hits > 0                                    # straight flights crash into each other
    obs, hits, closest, side = _fly(_SwapOrca, HEAD_ON, goals)
    assert hits == 0 and closest > 2 * COLLISION_RADIUS
    assert bool(obs["covered"].all()) and side > 0.3   # they swapped places by passing beside


def test_orca_lets_drones_far_apart_in_height_fly_over_each_other():
    start = [[-2.0, 0.0, 1.0], [2.0, 0.0, 2.0]]        # 1 m apart in height: they cannot touch
    goals = [[2.0, 0.0, 1.0], [-2.0, 0.0, 2.0]]
    obs, hits, _, side = _fly(_SwapOrca, start, goals)
    assert hits == 0 and bool(obs["covered"].all())
    assert side < 0.05                                 # straight lines, no detour


def _polyline_clearance(start, path, point):
    """Smallest horizontal distance from the polyline start → path to ``point``."""
    pts = np.concatenate([start[None], path])
    worst = np.inf
    for a, b in zip(pts[:-1], pts[1:]):
        d = b - a
        t = np.clip((point - a) @ d / max(d @ d, 1e-12), 0, 1)
        worst = min(worst, np.linalg.norm(a + t * d - point))
    return worst


class _SwapRRT(_Swap, DroneHRRTStar):
    pass


class _SwapVoronoi(_Swap, DroneHVoronoi):
    pass


@pytest.mark.parametrize("cls", [_SwapRRT, _SwapVoronoi])
def test_paths_go_around_a_drone_hovering_on_the_straight_line(cls):
    # drone 1 hovers on its landmark, in the middle of drone 0's straight line
    start = np.array([[-2.0, 0.0, 1.5], [0.0, 0.05, 1.5]])
    goals = np.array([[2.0, 0.0, 1.5], [0.0, 0.05, 1.5]])
    w = make("drone-5", num_envs=1, seed=0, num_agents=2, horizon=300)
    obs = w.reset(options={"agent_pos": start, "landmark_pos": goals})
    policy = cls(w)
    policy.reset(obs)
    policy.act(obs)
    path = policy.paths[0, 0]
    assert np.allclose(path[-1], goals[0, :2])
    assert _polyline_clearance(start[0, :2], path, start[1, :2]) >= 2 * COLLISION_RADIUS
    _, hits, closest, _ = _fly(cls, start, goals, horizon=300)   # and flies it without a crash
    assert hits == 0 and closest > 2 * COLLISION_RADIUS


def test_rrt_star_ignores_a_drone_it_cannot_touch():
    start = np.array([[-2.0, 0.0, 1.0], [0.0, 0.05, 2.0]])      # 1 m above drone 0's flight
    w = make("drone-5", num_envs=1, seed=0, num_agents=2, horizon=10)
    obs = w.reset(options={"agent_pos": start, "landmark_pos": start * [-1, 1, 1]})
    policy = _SwapRRT(w)
    policy.reset(obs)
    policy.act(obs)
    assert np.allclose(policy.paths[0, 0], [2.0, 0.0])          # straight to the goal


def test_altitude_gap_and_fence():
    z, gz = np.array([[1.5, 1.0, 2.0]]), np.array([[1.5, 1.0, 1.8]])
    gap = altitude_gap(z, gz)[0]
    assert np.allclose(gap, gap.T) and np.allclose(gap, [[0, 0.5, 0.3], [0.5, 0, 0.8], [0.3, 0.8, 0]])
    w = make("drone-5", num_envs=1, seed=0)
    policy = DroneHOrca(w)
    half = w.scenario.world_size / 2
    pos = np.array([[[half - dp.FENCE_MARGIN - 0.3, 0.0, 1.5], [0.0, half, 1.5]]])
    out = policy.fence(pos, np.array([[[4.0, 1.0], [0.0, 4.0]]]))
    assert np.allclose(out, [[[0.3 / dp.FENCE_TIME, 1.0], [0.0, -dp.FENCE_MARGIN / dp.FENCE_TIME]]])


def test_bad_input_is_one_clear_error():
    particle = make("mpe-5", num_envs=1, seed=0)
    for cls in DRONE_CLASSES.values():
        with pytest.raises(ValueError, match="expected a drone world"):
            cls(particle)
    w = make("drone-5", num_envs=1, seed=0)
    with pytest.raises(ValueError, match="unknown option"):
        make_policy("h-orca", w, horizon_typo=1)
    with pytest.raises(ValueError, match="global_step"):
        make_policy("h-bottleneck", w, global_step=0)


def test_varying_team_assigns_only_unreached_landmarks():
    w = make("drone-20to10", num_envs=2, seed=0, num_agents=6, team_after=2, change_step=1, horizon=20)
    obs = w.reset()
    obs, _ = w.step(torch.zeros(2, 6, 4))
    policy = make_policy("h-voronoi", w)
    policy.reset(obs)
    policy.act(obs)
    idx = policy.goal_index
    for b in range(2):
        alive = obs["alive"][b].numpy()
        assert (idx[b][~alive] == -1).all() and len(set(idx[b][alive].tolist())) == alive.sum() == 2
        assert (~obs["reached"][b].numpy()[idx[b][alive]]).all()


def test_h_capt_refuses_a_drone_world_clearly():
    from masp_lite.envs import make
    from masp_lite.policies import make_policy
    with pytest.raises(ValueError, match="h-capt: no policy for drone worlds; expected a particle scenario"):
        make_policy("h-capt", make("drone-5", num_envs=1, seed=0))
