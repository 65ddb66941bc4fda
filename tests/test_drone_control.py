"""Motor mixing, the Lee controller and h-greedy on the drone world."""
import math

import mujoco
import numpy as np
import pytest
import torch

from masp_lite.envs import make
from masp_lite.envs.drone_model import ARM_LENGTH, HUMMINGBIRD, MAX_THRUST, build_model, rotor_positions
from masp_lite.planners.geometric import (
    MIXER,
    LeeController,
    allocation_matrix,
    mixing_matrix,
    position_loop,
    quat_to_matrix,
    thrusts_to_commands,
)
from masp_lite.policies.drones import DroneHungarianGreedy


def test_mixing_matrix_round_trip_and_layout():
    A = allocation_matrix()
    assert np.allclose(MIXER @ A, np.eye(4)) and np.allclose(A @ MIXER, np.eye(4))
    wrench = np.array([7.0, 0.01, -0.02, 0.003])
    f = MIXER @ wrench
    assert np.allclose(A @ f, wrench)
    # "+" layout: rotor 0 on +x pitches the nose down (negative pitch moment), rotor 1 on +y rolls
    assert A[2, 0] == pytest.approx(-ARM_LENGTH) and A[1, 1] == pytest.approx(ARM_LENGTH)
    assert np.allclose(A[1], rotor_positions()[:, 1]) and np.allclose(A[2], -rotor_positions()[:, 0])
    x_layout = dict(arm_length=0.2, rotor_angles=np.deg2rad([45, 135, 225, 315]), directions=[1, -1, 1, -1],
                    yaw_ratio=0.02)
    assert np.allclose(mixing_matrix(**x_layout) @ allocation_matrix(**x_layout), np.eye(4))
    with pytest.raises(ValueError, match="4 values"):
        allocation_matrix(rotor_angles=[0, 1, 2])


def test_allocation_matches_mujoco_actuators():
    """The wrench MuJoCo applies for given rotor thrusts is A @ thrusts (body at identity)."""
    m = build_model(1)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    for _ in range(3):
        f = rng.uniform(0, MAX_THRUST, 4)
        d.ctrl[:] = f
        mujoco.mj_forward(m, d)
        q = d.qfrc_actuator[:6]
        got = np.array([q[2], q[3], q[4], q[5]])
        assert np.allclose(got, allocation_matrix() @ f, atol=1e-9)
        assert np.allclose(q[:2], 0)


def test_quaternion_matrix_agrees_with_mujoco():
    q = torch.tensor([0.9, 0.1, -0.3, 0.2], dtype=torch.float64)
    q = q / q.norm()
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q.numpy())
    assert np.allclose(quat_to_matrix(q).numpy(), R.reshape(3, 3))


def fly(w, obs, ctl, target, steps):
    errs = []
    for _ in range(steps):
        a = ctl(obs["agent_pos"], obs["agent_vel"], obs["agent_quat"], obs["agent_angvel"], target_pos=target)
        obs, info = w.step(a)
        errs.append((obs["agent_pos"] - target).norm(dim=-1).max().item())
    return obs, info, errs


def test_hover_holds_within_5cm_for_10s_after_a_push():
    steps = math.ceil(10 / 0.016)
    w = make("drone-5", num_envs=2, seed=0, horizon=steps + 10)
    obs = w.reset()
    target = obs["agent_pos"].clone()
    tilt = [math.cos(0.05), math.sin(0.05), 0, 0]  # 5.7° roll
    obs = w.reset(options={"agent_pos": target[0], "agent_vel": np.full((5, 3), 0.05),
                           "agent_quat": np.tile(tilt, (5, 1))})
    target = target[:1].expand(2, 5, 3)
    obs, info, errs = fly(w, obs, LeeController(), target, steps)
    assert info["alive"].all()
    assert max(errs) < 0.05
    assert errs[-1] < 0.005


def test_tracks_a_waypoint():
    w = make("drone-5", num_envs=1, seed=0, horizon=500)
    start = np.array([[-2.0, -2.0, 1.5], [-1.0, -2.0, 1.5], [0, -2.0, 1.5], [1.0, -2.0, 1.5], [2.0, -2.0, 1.5]])
    obs = w.reset(options={"agent_pos": start})
    target = torch.tensor(start, dtype=torch.float32).unsqueeze(0)
    target[0, 0] = torch.tensor([1.5, 1.5, 2.0])  # 5 m away, 0.5 m up
    obs, info, errs = fly(w, obs, LeeController(max_speed=2.0), target, 450)
    assert info["alive"].all() and errs[-1] < 0.05
    assert errs[100] > 0.5  # it takes time at 2 m/s: the test is not trivially satisfied


def test_commands_and_options():
    assert thrusts_to_commands(torch.tensor([0.0, MAX_THRUST, 2 * MAX_THRUST])).tolist() == [-1.0, 1.0, 1.0]
    hover = HUMMINGBIRD["mass"] * 9.81 / 4
    assert thrusts_to_commands(torch.tensor(hover)).item() == pytest.approx(2 * hover / MAX_THRUST - 1)
    state = [torch.randn(2, 3, k, generator=torch.Generator().manual_seed(k)) for k in (3, 3, 4, 3)]
    calls = []

    def spy(*args):
        calls.append(1)
        return position_loop(*args)
    assert torch.equal(LeeController(position_loop=spy)(*state), LeeController()(*state)) and calls
    with pytest.raises(ValueError, match="position_loop"):
        LeeController(position_loop=3)
    with pytest.raises(ValueError, match="kx"):
        LeeController(kx=-1)
    with pytest.raises(ValueError, match="max_speed"):
        LeeController(max_speed=0)
    with pytest.raises(ValueError, match="drone world"):
        DroneHungarianGreedy(make("mpe-5"))


@pytest.mark.parametrize("scenario", ["drone-5", "drone-20to10"])
def test_h_greedy_covers_landmarks(scenario):
    w = make(scenario, num_envs=3, seed=0)
    policy = DroneHungarianGreedy(w)
    obs = w.reset()
    policy.reset(obs)
    for _ in range(w.horizon):
        obs, info = w.step(policy.act(obs))
    if w.scenario.varying:
        assert info["reached"].float().mean() >= 0.9 and (info["alive"].sum(1) <= w.scenario.team_after).all()
    else:
        assert info["covered"].float().mean() >= 0.9


def test_h_greedy_through_the_registry_and_eval_rollout():
    from masp_lite import evaluation as ev
    from masp_lite.policies import make_policy
    w = make("drone-5", num_envs=2, seed=1, horizon=200)
    policy = make_policy("h-greedy", w)
    assert isinstance(policy, DroneHungarianGreedy)
    log, decision_s = ev.rollout(w, policy, episodes=2, seed=1)
    sr = ev.success_rate(log)
    assert sr.shape == (2,) and ((sr >= 0) & (sr <= 1)).all() and sr.mean() >= 0.6
    assert (ev.collision_rate(log) >= 0).all() and decision_s > 0
