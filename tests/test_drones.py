"""The MuJoCo quadrotor world: interface, rotor model, crashes, team change, determinism."""
import mujoco
import numpy as np
import pytest
import torch

from masp_lite.envs import make
from masp_lite.envs.drone_model import COLLISION_RADIUS, HOVER_COMMAND, HUMMINGBIRD, MAX_THRUST, build_model, save_xml
from masp_lite.envs.drones import CEILING, DroneWorld

HOVER = HOVER_COMMAND


def hover(w):
    return torch.full((w.num_envs, w.num_agents, 4), HOVER)


def test_make_dispatches_and_mirrors_the_particle_world():
    w = make("drone-5", num_envs=3, seed=0)
    assert isinstance(w, DroneWorld)
    assert (w.num_envs, w.num_agents, w.num_obstacles, w.horizon) == (3, 5, 0, 300)
    obs = w.reset()
    for k, shape in {"agent_pos": (3, 5, 3), "agent_vel": (3, 5, 3), "landmark_pos": (3, 5, 3),
                     "obstacle_pos": (3, 0, 3), "alive": (3, 5), "covered": (3, 5), "reached": (3, 5),
                     "t": (3,)}.items():
        assert tuple(obs[k].shape) == shape, k
    particle = make("mpe-5", num_envs=3, seed=0)
    _, pinfo = particle.step(torch.zeros(3, 5, dtype=torch.long))
    _, info = w.step(hover(w))
    assert set(info) == set(pinfo)
    assert info["collisions"].shape == (3,) and info["collisions"].dtype == torch.long
    assert info["agent_collisions"].shape == (3, 5) and info["done"].shape == (3,)
    assert not w.done.any()


def test_spawns_in_the_flight_volume_and_apart():
    w = make("drone-20", num_envs=4, seed=1)
    obs = w.reset()
    half = w.scenario.world_size / 2
    for key in ("agent_pos", "landmark_pos"):
        p = obs[key].double()
        assert (p[..., :2].abs() < half).all() and (p[..., 2] > 0.5).all() and (p[..., 2] < CEILING).all()
        d = torch.cdist(p, p) + torch.eye(20) * 1e9
        assert (d >= 2 * COLLISION_RADIUS).all()


def test_a_collision_radius_resizes_the_spheres_and_spaces_the_spawns():
    """``collision_radius`` (a drone scenario override): the crash test's sphere, the spawns' spacing and the
    world definition records name; particle worlds refuse it."""
    w = make("drone-20", num_envs=4, seed=1, collision_radius=0.4)
    hull = mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_GEOM, "d0_hull")
    assert w.model.geom_size[hull, 0] == pytest.approx(0.4) and w.scenario.world == {"collision_radius": 0.4}
    p = w.reset()["agent_pos"].double()
    assert (torch.cdist(p, p) + torch.eye(20) * 1e9 >= 0.8).all()
    assert make("drone-5", seed=0).scenario.world == {}  # the model's own sphere: the one drone world
    for bad, what in (({"scenario": "drone-5", "collision_radius": 0.0}, "collision_radius > 0"),
                      ({"scenario": "mpe-5", "collision_radius": 0.3}, "only for drone scenarios")):
        with pytest.raises(ValueError, match=what):
            make(**bad)


def test_hover_command_balances_the_weight():
    # in steady state thrust = (c + 1) / 2 * f_max; four rotors at HOVER lift exactly m g
    assert 4 * (HOVER + 1) / 2 * MAX_THRUST == pytest.approx(HUMMINGBIRD["mass"] * 9.81)
    w = make("drone-5", num_envs=2, seed=0)
    obs0 = w.reset()
    for _ in range(100):
        obs, info = w.step(hover(w))
    assert torch.allclose(obs["agent_pos"], obs0["agent_pos"], atol=1e-5)
    assert info["alive"].all() and (info["collisions"] == 0).all()


def test_rotor_lag_and_thrust_map():
    w = make("drone-5", num_envs=1, seed=0)
    w.reset()
    a = hover(w)
    a[0, 0] = 1.0
    obs, _ = w.step(a)
    u0 = np.sqrt((HOVER + 1) / 2)
    assert obs["throttle"][0, 0, 0].item() == pytest.approx(u0 + 0.43 * (1.0 - u0), rel=1e-6)
    for _ in range(15):
        obs, _ = w.step(a)
    assert obs["throttle"][0, 0].double().numpy() == pytest.approx(1.0, abs=1e-3)
    assert obs["agent_vel"][0, 0, 2] > 1.0  # full throttle climbs


def test_drone_drone_crash_is_one_event_and_both_leave():
    w = make("drone-5", num_envs=1, seed=0)
    pos = np.array([[-1.0, 0, 1.5], [-1.0 + 2 * COLLISION_RADIUS + 0.2, 0, 1.5], [2, 2, 1.5], [2, -2, 1.5],
                    [-2, 2, 1.5]])
    vel = np.zeros((5, 3))
    vel[0, 0], vel[1, 0] = 2.0, -2.0
    w.reset(options={"agent_pos": pos, "agent_vel": vel})
    total = torch.zeros(1, dtype=torch.long)
    for _ in range(20):
        obs, info = w.step(hover(w))
        total += info["collisions"]
    assert total.item() == 1
    assert obs["alive"][0].tolist() == [False, False, True, True, True]
    frozen = obs["agent_pos"][0, :2].clone()
    obs, info = w.step(hover(w))
    assert torch.equal(obs["agent_pos"][0, :2], frozen) and info["collisions"].item() == 0


def test_a_given_start_in_contact_is_accepted_and_crashes_at_once():
    w = make("drone-5", num_envs=1, seed=0)
    pos = np.array([[0.0, 0, 1.5], [COLLISION_RADIUS, 0, 1.5], [2, 2, 1.5], [2, -2, 1.5], [-2, 2, 1.5]])
    w.reset(options={"agent_pos": pos})                           # overlapping spheres: allowed
    obs, info = w.step(hover(w))
    assert info["collisions"].item() == 1 and obs["alive"][0].tolist() == [False, False, True, True, True]
    with pytest.raises(ValueError, match="same point"):
        w.reset(options={"agent_pos": np.zeros((5, 3)) + [0, 0, 1.5]})


def test_floor_and_map_exit_are_crashes():
    w = make("drone-5", num_envs=1, seed=0)
    half = w.scenario.world_size / 2
    pos = np.array([[0, 0, 1.0], [half - 0.35, 0, 1.5], [2, 2, 1.5], [2, -2, 1.5], [-2, 2, 1.5]])
    vel = np.zeros((5, 3))
    vel[1, 0] = 3.0
    w.reset(options={"agent_pos": pos, "agent_vel": vel})
    a = hover(w)
    a[0, 0] = -1.0  # drone 0: motors off, it falls
    alive_at = []
    for _ in range(60):
        obs, info = w.step(a)
        alive_at.append(info["alive"][0].tolist())
    assert obs["alive"][0].tolist() == [False, False, True, True, True]
    assert alive_at[0][1] is True  # drone 1 needs a few steps to reach the border


def test_reach_distance_in_3d_and_crashed_drones_do_not_cover():
    w = make("drone-5", num_envs=1, seed=0)
    r = w.reach_distance
    assert r == pytest.approx(HUMMINGBIRD["arm_length"] + w.scenario.landmark_radius)
    pos = np.array([[0, 0, 1.5], [2, 0, 1.5], [-2, 0, 1.5], [0, 2, 1.5], [0, -2, 1.5]])
    lms = pos + np.array([[0, 0, r - 0.01], [0, 0, r + 0.01], [1, 1, 0], [1, -1, 0], [-1, 1, 0.2]])
    obs = w.reset(options={"agent_pos": pos, "landmark_pos": lms})
    assert obs["covered"][0].tolist() == [True, False, False, False, False]
    a = hover(w)
    a[0, 0] = -1.0  # drone 0 falls to the floor
    for _ in range(80):
        obs, _ = w.step(a)
    assert not obs["alive"][0, 0] and not obs["covered"][0, 0] and obs["reached"][0, 0]


def test_team_change_drops_to_team_after():
    w = make("drone-20to10", num_envs=2, seed=3, horizon=30)
    assert w.scenario.change_step == 10
    w.reset()
    for t in range(1, 13):
        obs, info = w.step(hover(w))
        assert info["alive"].sum(1).tolist() == ([20, 20] if t < 10 else [10, 10])
    gone = ~obs["alive"][0]
    assert (obs["agent_pos"][0, gone, 2] < CEILING).all()  # observed where they left, not parked


def test_same_seed_same_numbers_and_env_ids_reset():
    def run(seed):
        w = make("drone-5", num_envs=2, seed=seed)
        g = torch.Generator().manual_seed(5)
        out = [w.reset()["landmark_pos"].clone()]
        for _ in range(30):
            obs, _ = w.step((torch.rand(2, 5, 4, generator=g) * 0.2 + HOVER - 0.1).clamp(-1, 1))
        return out + [obs["agent_pos"].clone(), obs["agent_quat"].clone()]
    a, b, c = run(7), run(7), run(8)
    assert all(torch.equal(x, y) for x, y in zip(a, b))
    assert not torch.equal(a[0], c[0])
    w = make("drone-5", num_envs=3, seed=0)
    for _ in range(5):
        w.step(hover(w))
    before = w.observe()["landmark_pos"].clone()
    obs = w.reset(env_ids=[1])
    assert obs["t"].tolist() == [5, 0, 5]
    assert torch.equal(obs["landmark_pos"][[0, 2]], before[[0, 2]])


@pytest.mark.parametrize("bad, match", [
    (torch.zeros(2, 5, 3), "shape"), (torch.zeros(2, 5, 4, dtype=torch.long), "float"),
    (torch.full((2, 5, 4), float("nan")), "finite"), (torch.full((2, 5, 4), 1.5), r"\[-1, 1\]"),
    ([[0.0]], "float tensor"),
])
def test_bad_actions(bad, match):
    w = make("drone-5", num_envs=2, seed=0)
    with pytest.raises(ValueError, match=match):
        w.step(bad)


def test_bad_scenarios_and_options():
    with pytest.raises(ValueError, match="unknown scenario"):
        make("drone-7")
    with pytest.raises(ValueError, match="drone scenario"):
        DroneWorld("mpe-5")
    w = make("drone-5", num_envs=1, seed=0)
    with pytest.raises(ValueError, match="agent_pos"):
        w.reset(options={"agent_pos": np.zeros((4, 3))})
    with pytest.raises(ValueError, match="same point"):
        w.reset(options={"agent_pos": np.zeros((5, 3)) + [0, 0, 1.5]})
    with pytest.raises(ValueError, match="unknown reset option"):
        w.reset(options={"obstacles": 1})
    w2 = make("drone-5", num_envs=1, seed=0, horizon=2)
    w2.step(hover(w2)), w2.step(hover(w2))
    with pytest.raises(ValueError, match="reset"):
        w2.step(hover(w2))


def test_model_saves_and_reloads(tmp_path):
    path = save_xml(str(tmp_path / "drones.xml"), 3)
    m = mujoco.MjModel.from_xml_path(path)
    assert m.nu == 12 and m.nbody == 4 and m.nsensor == 6
    assert m.body_mass[1] == pytest.approx(HUMMINGBIRD["mass"])
    assert np.allclose(m.body_inertia[1], HUMMINGBIRD["inertia"])
    assert build_model(2).nu == 8


def test_pettingzoo_face_passes_the_api_and_seed_tests():
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    from masp_lite.envs import parallel_env
    env = parallel_env("drone-5")
    assert type(env).__name__ == "DroneParallelEnv"
    parallel_api_test(env, num_cycles=60)
    parallel_seed_test(lambda: parallel_env("drone-5"))


def test_pettingzoo_reset_options_and_bad_actions():
    from masp_lite.envs import parallel_env
    env = parallel_env("drone-5")
    start = np.array([[-2.0, -2.0, 1.5], [-1.0, -2.0, 1.5], [0, -2.0, 1.5], [1.0, -2.0, 1.5], [2.0, -2.0, 1.5]])
    obs, _ = env.reset(seed=0, options={"agent_pos": start})
    assert obs["drone_3"][:3].tolist() == pytest.approx([1.0, -2.0, 1.5])
    assert env.observation_space("drone_0").shape == (59,)
    with pytest.raises(ValueError, match=r"\[-1, 1\]"):
        env.step({a: np.full(4, 2.0) for a in env.agents})
    with pytest.raises(ValueError, match="one action"):
        env.step({"drone_0": np.zeros(4)})
    with pytest.raises(ValueError, match="render_mode"):
        parallel_env("drone-5", render_mode="human")


def test_bench_drones_measures_both_sides(capsys):
    import argparse

    from masp_lite.bench import drones as bench
    r = bench.measure(2, seconds=0.1, rounds=1)
    assert r["env_steps_per_s"] > 0 and r["raw_env_steps_per_s"] > 0
    assert r["overhead"] == pytest.approx(r["raw_env_steps_per_s"] / r["env_steps_per_s"])
    with pytest.raises(ValueError, match="seconds"):
        bench.run(argparse.Namespace(seconds=0, rounds=1, worlds=[1], threads=1, json=None))


def test_reset_of_one_episode_brings_its_crashed_drone_back():
    w = make("drone-5", num_envs=2, seed=0)
    a = hover(w)
    a[0, 0] = -1.0  # episode 0, drone 0 falls and crashes
    for _ in range(80):
        obs, _ = w.step(a)
    assert obs["alive"].tolist() == [[False] + [True] * 4, [True] * 5]
    start = w.reset(env_ids=[0])["agent_pos"].clone()
    a[0, 0] = HOVER
    for _ in range(50):
        obs, info = w.step(a)
    assert info["alive"].all() and torch.allclose(obs["agent_pos"], start, atol=1e-5)


def _run_both(actions, steps, **reset):
    """One world (one MjData, mj_step) and two worlds (mujoco.batch) from the same start."""
    one, two = (DroneWorld("drone-5", num_envs=b, seed=0, dtype=torch.float64) for b in (1, 2))
    assert one.batch is None and two.batch is not None  # the two physics paths
    out = []
    for w in (one, two):
        w.reset(options=reset)
        rows = []
        for k in range(steps):
            if k == steps // 2:
                w.reset(env_ids=[0], options=reset)  # a reset mid-run, of the first episode only
            obs, info = w.step(actions.expand(w.num_envs, 5, 4))
            rows.append({**{"obs_" + k: v.clone() for k, v in obs.items()}, **info})
        out.append((w, rows))
    return out


def test_one_world_path_matches_the_batched_path_bit_for_bit():
    pos = np.array([[-1.0, 0, 1.5], [-1.0 + 2 * COLLISION_RADIUS + 0.2, 0, 1.5], [2, 2, 1.5], [2, -2, 1.5],
                    [-2, 2, 1.5]])
    vel = np.zeros((5, 3))
    vel[0, 0], vel[1, 0], vel[2, 2] = 2.0, -2.0, 0.3  # a crash, a climb
    a = torch.full((1, 5, 4), HOVER, dtype=torch.float64)
    a[0, 3, :2] = -0.3  # drone 3 tilts away and drifts
    (one, rows1), (two, rows2) = _run_both(a, 60, agent_pos=pos, agent_vel=vel, landmark_pos=pos + 0.1)
    assert sum(int(r["collisions"][0]) for r in rows1) >= 1  # the crash path ran
    for step, (r1, r2) in enumerate(zip(rows1, rows2)):
        for k, v in r1.items():  # episode 1 of the batch is not reset mid-run
            assert torch.equal(v[0], r2[k][0]) and (step >= 30 or torch.equal(v[0], r2[k][1])), k
    d1, d2 = one.get_data(0), two.get_data(0)
    assert np.array_equal(d1.qpos, d2.qpos) and np.array_equal(d1.qvel, d2.qvel)
    with pytest.raises(ValueError, match="env"):
        one.get_data(1)


def test_skipped_coverage_tests_give_the_exact_answer():
    w = DroneWorld("drone-5", num_envs=2, seed=0, dtype=torch.float64)
    pos = np.array([[-2.0, -2, 1.5], [-2, 0, 1.5], [-2, 2, 1.5], [1, -2, 1.5], [1, 1, 1.5]])
    lms = pos + np.array([[0.5, 0, 0.1], [0.4, 0, -0.1], [0.6, 0.1, 0], [0.5, 0, 0], [-0.5, 0, 0.05]])
    vel = np.zeros((5, 3))
    vel[:, 0] = [0.4, 0.3, 0.5, 0.35, -0.3]  # gliding through their landmarks
    w.reset(options={"agent_pos": pos, "agent_vel": vel, "landmark_pos": lms})
    exact, check = [0], w._check_coverage

    def counted(p):
        exact[0] += 1
        check(p)
    w._check_coverage = counted
    r2, seen = w.reach_distance ** 2, []
    for _ in range(200):
        obs, info = w.step(hover(w).double())
        d = w.state[:, :, None, :3] - w.landmark_pos[:, None]
        covered = ((np.einsum("bnlk,bnlk->bnl", d, d) <= r2) & w.alive[..., None]).any(axis=1)
        assert np.array_equal(info["covered"].numpy(), covered)
        seen.append(covered.sum())
    assert max(seen) > 0 and seen[-1] == 0 and info["reached"].all()  # reached, then left behind
    assert 0 < exact[0] < 200  # the test was skipped on some steps, run on others


def test_observations_handed_out_are_never_written_afterwards():
    w = make("drone-5", num_envs=1, seed=0)
    pos = np.array([[0.0, 0, 1.5], [2, 0, 1.5], [-2, 0, 1.5], [0, 2, 1.5], [0, -2, 1.5]])
    w.reset(options={"agent_pos": pos, "landmark_pos": pos + [0.5, 0, 0], "agent_vel": np.tile([0.5, 0, 0], (5, 1))})
    a = hover(w)
    a[0, 1] = -1.0  # drone 1 falls and crashes
    kept = [w.step(a) for _ in range(80)]
    copies = [({k: v.clone() for k, v in o.items()}, {k: v.clone() for k, v in i.items()}) for o, i in kept]
    for _ in range(20):
        w.step(a)
    for (o, i), (oc, ic) in zip(kept, copies):
        assert all(torch.equal(o[k], oc[k]) for k in o) and all(torch.equal(i[k], ic[k]) for k in i)
    assert any(i["collisions"].item() for _, i in copies) and any(o["covered"].any() for o, _ in copies)
