"""Reference methods: the MPE velocity controller, random and h-greedy policies."""
import pytest
import torch

from masp_lite.envs import PHYSICS, make
from masp_lite.evaluation import rollout, steps, success_rate
from masp_lite.policies import make_policy
from masp_lite.policies.reference import MAX_SPEED, braking_speed, velocity_to_action


def test_velocity_to_action_picks_the_closest_next_velocity():
    vel = torch.zeros(5, 2)
    desired = torch.tensor([[0.0, 0.0], [-1.0, 0.1], [1.0, -0.1], [0.1, -1.0], [0.0, 1.0]])
    assert velocity_to_action(vel, desired).tolist() == [0, 1, 2, 3, 4]
    # moving fast in +x with a zero target: the -x action brakes hardest
    assert velocity_to_action(torch.tensor([[2.0, 0.0]]), torch.zeros(1, 2)).tolist() == [1]
    with pytest.raises(ValueError, match="expected"):
        velocity_to_action(torch.zeros(3, 2), torch.zeros(3, 3))


def test_braking_speed_stops_within_the_distance():
    assert MAX_SPEED == pytest.approx(2.0)
    d = torch.linspace(0.0, 1.0, 41, dtype=torch.float64)
    v = braking_speed(d)
    assert (v[1:] >= v[:-1]).all() and v[0] == 0 and v[-1] == pytest.approx(MAX_SPEED)
    # simulate full braking from v: travelled distance (continuous steps) stays within d
    c, u = 1 - PHYSICS["damping"], MAX_SPEED
    speed, travelled = v.clone(), torch.zeros_like(v)
    for _ in range(30):
        travelled += PHYSICS["dt"] * speed.clamp(min=0)
        speed = (c * speed - u * (1 - c)).clamp(min=0)
    uncapped = v < MAX_SPEED - 1e-6
    assert (travelled[uncapped] <= d[uncapped] + 0.03).all()


def test_random_policy_is_seeded():
    w = make("mpe-5", num_envs=3, seed=0)
    a1 = make_policy("random", w, seed=4).act(w.observe())
    a2 = make_policy("random", w, seed=4).act(w.observe())
    assert torch.equal(a1, a2) and a1.shape == (3, 5) and a1.dtype == torch.long
    with pytest.raises(ValueError, match="seed"):
        make_policy("random", w, seed="x")


def test_h_greedy_solves_mpe5():
    # without obstacles the straight line always works: every episode covers every landmark
    w = make("mpe-5", num_envs=8, seed=0, num_obstacles=0)
    log, _ = rollout(w, make_policy("h-greedy", w), episodes=8, seed=0)
    assert success_rate(log).min().item() == 1.0
    assert steps(log).max().item() < w.horizon
    # with the paper's 5 obstacles an agent can get stuck behind one now and then
    w = make("mpe-5", num_envs=16, seed=0)
    log, _ = rollout(w, make_policy("h-greedy", w), episodes=16, seed=1)
    assert success_rate(log).mean().item() >= 0.9


def test_h_greedy_on_paper_scenarios_mostly_succeeds():
    w = make("mpe-20", num_envs=16, seed=0)
    log, _ = rollout(w, make_policy("h-greedy", w), episodes=16, seed=1)
    assert success_rate(log).mean().item() >= 0.95
    w = make("mpe-20to10", num_envs=16, seed=0)
    log, _ = rollout(w, make_policy("h-greedy", w), episodes=16, seed=1)
    assert success_rate(log).mean().item() >= 0.95 and log.alive[:, -1].sum(1).eq(10).all()


def test_h_greedy_reassigns_every_global_step_and_validates():
    w = make("mpe-5", num_envs=2, seed=0)
    p = make_policy("h-greedy", w, global_step=3)
    obs = w.reset(seed=0)
    p.reset(obs)
    p.act(obs)
    assert p.assignment.shape == (2, 5) and sorted(p.assignment[0].tolist()) == [0, 1, 2, 3, 4]
    with pytest.raises(ValueError, match="global_step"):
        make_policy("h-greedy", w, global_step=0)
    with pytest.raises(ValueError, match="unknown option"):
        make_policy("h-greedy", w, speed=3)
    with pytest.raises(ValueError, match="power"):
        make_policy("h-greedy", w, power=0)


def test_h_greedy_power_sets_the_assignment_cost():
    from masp_lite.algos.assignment import hungarian
    w = make("mpe-20", num_envs=8, seed=1)
    obs = w.reset(seed=1)
    for power in (1, 2):
        p = make_policy("h-greedy", w, power=power)
        p.reset(obs)
        p.act(obs)
        assert torch.equal(p.assignment, hungarian(obs["agent_pos"], obs["landmark_pos"], obs["alive"], power=power))
    plain = hungarian(obs["agent_pos"], obs["landmark_pos"], obs["alive"])
    assert not torch.equal(plain, hungarian(obs["agent_pos"], obs["landmark_pos"], obs["alive"], power=2))


def test_h_greedy_hands_drone_worlds_to_the_drone_controller():
    drone_control = pytest.importorskip("masp_lite.policies.drones")
    w = make("drone-5", num_envs=1, seed=0)
    assert isinstance(make_policy("h-greedy", w), drone_control.DroneHungarianGreedy)


def test_h_greedy_reassigns_as_soon_as_the_team_shrinks():
    w = make("mpe-20to10", num_envs=3, seed=0, change_step=4)
    p = make_policy("h-greedy", w, global_step=3)
    obs = w.reset(seed=0)
    p.reset(obs)
    for _ in range(4):
        obs, _ = w.step(p.act(obs))
    before = p.assignment.clone()  # made at t = 3 for the full team
    assert (before[~obs["alive"]] >= 0).any()  # some dropped agents had goals
    p.act(obs)  # t = 4 is no global step, but the team has just changed
    assert torch.equal(p.assignment, p.assign(obs))
    assert (p.assignment[~obs["alive"]] == -1).all()


def test_h_capt_and_h_bottleneck_are_h_greedy_with_another_assignment():
    from masp_lite.algos.team import bottleneck
    from masp_lite.evaluation import rollout
    w = make("mpe-20", num_envs=4, seed=5)
    obs = w.reset(seed=5)
    capt, squared = make_policy("h-capt", w), make_policy("h-greedy", w, power=2)
    capt.reset(obs), squared.reset(obs)
    assert torch.equal(capt.act(obs), squared.act(obs))
    mm = make_policy("h-bottleneck", w)
    mm.reset(obs)
    mm.act(obs)
    assert torch.equal(mm.assignment, bottleneck(obs["agent_pos"], obs["landmark_pos"], obs["alive"]))
    logs = {m: rollout(w, make_policy(m, w), 8, seed=1)[0] for m in ("h-greedy", "h-bottleneck")}
    from masp_lite.evaluation import steps
    assert steps(logs["h-bottleneck"]).mean() < steps(logs["h-greedy"]).mean()  # the longest trip sets Steps
    with pytest.raises(ValueError, match="cost"):
        make_policy("h-greedy", w, cost="max")


def test_sequential_team_protocol_keeps_goals_after_the_shrink_until_reached():
    w = make("mpe-20to10", num_envs=3, seed=2)
    obs = w.reset(seed=2)
    pol = make_policy("h-greedy", w, team_protocol="sequential")
    plain = make_policy("h-greedy", w)
    pol.reset(obs), plain.reset(obs)
    changed = 0
    for _ in range(w.horizon):
        before = None if pol.assignment is None else pol.assignment.clone()
        reached_before = obs["reached"].clone()
        act = pol.act(obs)
        if not bool(obs["alive"].all()):                      # after the shrink
            assert before is not None
            held = (before >= 0) & obs["alive"]
            goal_reached = torch.gather(reached_before, 1, before.clamp(min=0)) & held
            kept = held & ~goal_reached & (pol.assignment == before)
            moved = held & ~goal_reached & (pol.assignment != before)
            assert not bool(moved.any()) or t_first_shrink(obs, w)  # only the one fresh assignment at the change
            changed += int(kept.sum())
        else:
            assert torch.equal(act, plain.act(obs))             # before the shrink: the plain assignment
        obs, _ = w.step(act)
    assert changed > 0
    with pytest.raises(ValueError, match="team_protocol"):
        make_policy("h-orca", w, team_protocol="greedy")


def t_first_shrink(obs, w):
    """True at the first decision after the team change (the one fresh assignment)."""
    return bool((obs["t"] == w.scenario.change_step).all())
