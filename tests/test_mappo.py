"""MAPPO pieces and MASP's rewards on hand-worked numbers."""
import math

import pytest
import torch

from masp_lite.algos import mappo
from masp_lite.algos.assignment import hungarian
from masp_lite.algos.mappo import RolloutStorage, ValueNorm, clipped_surrogate, gae, ppo_update, value_loss
from masp_lite.algos.rewards import executor_reward, goal_matcher_reward, repeat_counts
from masp_lite.config import NetConfig, PPOConfig, RewardConfig, RunConfig, TrainConfig


def test_gae_one_step_and_lambda_one_is_discounted_return():
    adv, ret = gae(torch.tensor([1.0]), torch.tensor([0.0]), torch.tensor(2.0), gamma=0.5, lam=0.9)
    assert float(adv[0]) == pytest.approx(2.0) and float(ret[0]) == pytest.approx(2.0)
    torch.manual_seed(0)
    r, v = torch.randn(6, 3), torch.randn(6, 3)
    adv, ret = gae(r, v, torch.zeros(3), gamma=0.9, lam=1.0)
    disc = torch.zeros(6, 3)
    acc = torch.zeros(3)
    for t in reversed(range(6)):
        acc = r[t] + 0.9 * acc
        disc[t] = acc
    torch.testing.assert_close(ret, disc)
    torch.testing.assert_close(adv, disc - v)


def test_gae_lambda_zero_is_td_error_and_done_cuts():
    r, v = torch.tensor([1.0, 2.0, 3.0]), torch.tensor([0.5, 1.0, 1.5])
    adv, _ = gae(r, v, torch.tensor(4.0), gamma=0.9, lam=0.0)
    torch.testing.assert_close(adv, torch.tensor([1 + 0.9 * 1.0 - 0.5, 2 + 0.9 * 1.5 - 1.0, 3 + 0.9 * 4 - 1.5]))
    adv, _ = gae(r, v, torch.tensor(4.0), gamma=0.9, lam=1.0, not_done=torch.tensor([1.0, 0.0, 1.0]))
    assert float(adv[1]) == pytest.approx(2.0 - 1.0)      # episode ended at step 1: no bootstrap


def test_clipped_surrogate():
    old = torch.zeros(3)
    logp = torch.log(torch.tensor([1.1, 1.5, 0.5]))
    adv = torch.tensor([1.0, 1.0, -1.0])
    # ratios 1.1 (inside), 1.5 -> clipped 1.2 for A > 0, 0.5 -> clipped 0.8 for A < 0: min(-0.5, -0.8) = -0.8
    expect = -(1.1 + 1.2 - 0.8) / 3
    assert float(clipped_surrogate(logp, old, adv, 0.2)) == pytest.approx(expect, rel=1e-5)
    mask = torch.tensor([True, False, False])
    assert float(clipped_surrogate(logp, old, adv, 0.2, mask)) == pytest.approx(-1.1, rel=1e-5)


def test_value_loss_takes_worse_of_clipped_and_unclipped():
    v, old, tgt = torch.tensor([2.0]), torch.tensor([0.0]), torch.tensor([3.0])
    # unclipped error 1 -> 0.5; clipped value 0.2 -> error 2.8 -> 3.92
    assert float(value_loss(v, old, tgt, clip=0.2, delta=10.0)) == pytest.approx(0.5 * 2.8**2)
    # Huber beyond delta is linear
    assert float(value_loss(torch.tensor([0.0]), torch.tensor([0.0]), torch.tensor([20.0]), 0.2, 10.0)) \
        == pytest.approx(10.0 * (20.0 - 5.0))


def test_value_norm_round_trip_and_statistics():
    vn = ValueNorm(beta=0.9)
    g = torch.Generator().manual_seed(0)
    for _ in range(200):
        vn.update(torch.randn(1000, generator=g) * 3 + 5)
    x = torch.tensor([5.0, 8.0])
    z = vn.normalize(x)
    assert float(z[0]) == pytest.approx(0.0, abs=0.1) and float(z[1]) == pytest.approx(1.0, abs=0.1)
    torch.testing.assert_close(vn.denormalize(z), x)


def test_rollout_storage_minibatches_partition_rows():
    s = RolloutStorage()
    for t in range(5):
        s.add(x=torch.arange(3) + 10 * t)
    data = s.stacked()
    seen = torch.cat([mb["x"] for mb in RolloutStorage.minibatches(data, 4, torch.Generator().manual_seed(1))])
    assert sorted(seen.tolist()) == sorted(data["x"].flatten().tolist())


def test_ppo_update_moves_policy_towards_positive_advantages():
    torch.manual_seed(0)
    actor, critic = torch.nn.Linear(2, 3), torch.nn.Linear(2, 1)
    opt = torch.optim.Adam(list(actor.parameters()) + list(critic.parameters()), lr=1e-2)
    x = torch.ones(8, 4, 2, 2)
    actions = torch.zeros(8, 4, 2, dtype=torch.long)
    actions[4:] = 1                                   # action 1 was bad, action 0 good
    adv = torch.where(actions == 0, 1.0, -1.0)
    with torch.no_grad():
        before = torch.softmax(actor(x[0, 0, 0]), -1)
        logp = torch.gather(torch.log_softmax(actor(x), -1), -1, actions.unsqueeze(-1)).squeeze(-1)
    data = {"x": x, "actions": actions, "logp": logp, "values": torch.zeros(8, 4, 2),
            "returns": torch.ones(8, 4, 2), "advantages": adv, "mask": torch.ones(8, 4, 2, dtype=torch.bool)}
    cfg = PPOConfig(ppo_epochs=3, num_minibatches=2)
    stats = ppo_update(data, lambda mb: (actor(mb["x"]), critic(mb["x"]).squeeze(-1)), actor, critic, opt, cfg,
                       ValueNorm(), torch.Generator().manual_seed(0))
    assert tuple(stats) == mappo.UPDATE_STATS
    assert stats["approx_kl"] > 0 and 0 <= stats["clip_fraction"] <= 1  # the policy moved
    with torch.no_grad():
        after = torch.softmax(actor(x[0, 0, 0]), -1)
    assert after[0] > before[0] and after[1] < before[1]


def _one_minibatch_update(old_shift: torch.Tensor, returns: torch.Tensor, advantages: torch.Tensor) -> dict:
    """``ppo_update`` with one epoch of one minibatch and a zero learning rate (the policy stays put), the stored
    log-probabilities those of the actor minus ``old_shift``."""
    torch.manual_seed(0)
    actor, critic = torch.nn.Linear(2, 3), torch.nn.Linear(2, 1)
    x = torch.randn(2, 2, 2, 2)
    actions = torch.zeros(2, 2, 2, dtype=torch.long)
    with torch.no_grad():
        logp = torch.log_softmax(actor(x), -1)[..., 0]
    data = {"x": x, "actions": actions, "logp": logp - old_shift, "values": torch.zeros(2, 2, 2),
            "returns": returns, "advantages": advantages, "mask": torch.ones(2, 2, 2, dtype=torch.bool)}
    opt = torch.optim.Adam(list(actor.parameters()) + list(critic.parameters()), lr=0.0)
    return ppo_update(data, lambda mb: (actor(mb["x"]), critic(mb["x"]).squeeze(-1)), actor, critic, opt,
                      PPOConfig(ppo_epochs=1, num_minibatches=1, clip=0.2), ValueNorm(),
                      torch.Generator().manual_seed(0))


def test_ppo_health_approximate_kl_and_clip_fraction_by_hand():
    """Ratio 1 everywhere: KL 0, nothing clipped. Half the samples at log-ratio 0.5 (ratio 1.65, outside
    [0.8, 1.2]): clip fraction 1/2 and KL the mean of (rho - 1) - log rho = (e^0.5 - 1.5) / 2."""
    returns, adv = torch.randn(2, 2, 2, generator=torch.Generator().manual_seed(1)), torch.ones(2, 2, 2)
    same = _one_minibatch_update(torch.zeros(2, 2, 2), returns, adv)
    assert same["approx_kl"] == pytest.approx(0.0, abs=1e-7) and same["clip_fraction"] == 0.0
    shift = torch.zeros(2, 2, 2)
    shift[0] = 0.5  # the new policy likes these actions e^0.5 times more than the one that collected them
    moved = _one_minibatch_update(shift, returns, adv)
    assert moved["clip_fraction"] == pytest.approx(0.5)
    assert moved["approx_kl"] == pytest.approx((math.exp(0.5) - 1.5) / 2, rel=1e-5)


def test_explained_variance_of_the_values_at_collection():
    """1 when the values are the returns, 0 for their mean, negative when worse; masked entries do not count.
    ``ppo_update`` reads the values at collection as returns minus the raw advantages."""
    r = torch.tensor([1.0, 2.0, 3.0, 4.0])
    assert mappo.explained_variance(r, r) == pytest.approx(1.0)
    assert mappo.explained_variance(torch.full((4,), 2.5), r) == pytest.approx(0.0)
    assert mappo.explained_variance(r.flip(0), r) == pytest.approx(1 - 5.0 / 1.25)  # Var(r - flip r) = 5, Var(r) = 1.25
    mask = torch.tensor([True, True, True, False])
    assert mappo.explained_variance(torch.tensor([1.0, 2.0, 3.0, 100.0]), r, mask) == pytest.approx(1.0)
    assert math.isnan(mappo.explained_variance(r, torch.ones(4)))  # returns that do not vary: undefined
    returns = torch.randn(2, 2, 2, generator=torch.Generator().manual_seed(2))
    assert _one_minibatch_update(torch.zeros(2, 2, 2), returns, torch.zeros(2, 2, 2))["explained_variance"] == \
        pytest.approx(1.0)  # zero advantages: the critic predicted every return
    adv = returns - returns.mean()  # values at collection all equal the mean return
    assert _one_minibatch_update(torch.zeros(2, 2, 2), returns, adv)["explained_variance"] == \
        pytest.approx(0.0, abs=1e-6)


def test_config_rejects_bad_values():
    with pytest.raises(ValueError, match="num_envs"):
        RunConfig(num_envs=0)
    with pytest.raises(ValueError, match="gamma"):
        PPOConfig(gamma=1.5)
    with pytest.raises(ValueError, match="group_size"):
        NetConfig(group_size=1)
    with pytest.raises(ValueError, match="team_bonus"):  # a setting that was tried and not kept
        TrainConfig.from_flat({"team_bonus": 0.5})


# ----------------------------------------------------------------------------- rewards
AGENTS = torch.tensor([[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]])
GOALS = torch.tensor([[[0.0, 1.0], [1.0, 1.0], [2.0, 1.0]]])  # Hungarian: agent i -> goal i
ALIVE = torch.ones(1, 3, dtype=torch.bool)


def test_r_gm_zero_when_matching_hungarian():
    assert hungarian(AGENTS, GOALS).tolist() == [[0, 1, 2]]
    r = goal_matcher_reward(AGENTS, GOALS, torch.tensor([[0, 1, 2]]), ALIVE)
    assert r.tolist() == [[0.0, 0.0, 0.0]]


def test_r_gm_repeats():
    goals = torch.tensor([[1, 1, 2]])
    assert repeat_counts(goals, ALIVE, 3).tolist() == [[1, 1, 0]]
    r = goal_matcher_reward(AGENTS, GOALS, goals, ALIVE)
    # agent 0: not Hungarian, one repeat -> -(1 + 1/3); agent 1 picked its Hungarian goal -> 0
    assert r[0, 0].item() == pytest.approx(-(1 + 1 / 3))
    assert r[0, 1].item() == 0.0 and r[0, 2].item() == 0.0


def test_r_gm_with_a_squared_reference():
    """power=2: the reference minimises squared distances and D_m, D_h are squared totals."""
    a = torch.tensor([[[0.0, 0.0], [1.0, 0.0]]])
    g = torch.tensor([[[1.0, 0.0], [2.0, 0.3]]])
    alive = torch.ones(1, 2, dtype=torch.bool)
    total = goal_matcher_reward(a, g, torch.tensor([[1, 0]]), alive)       # the total-distance optimum
    assert total.tolist() == [[0.0, 0.0]]
    r = goal_matcher_reward(a, g, torch.tensor([[1, 0]]), alive, power=2)  # not the squared optimum
    d_h, d_m = 1 + 1.09, 2.0**2 + 0.3**2
    assert r[0].tolist() == pytest.approx([-(1 - d_h / d_m)] * 2, rel=1e-5)
    assert goal_matcher_reward(a, g, torch.tensor([[0, 1]]), alive, power=2).tolist() == [[0.0, 0.0]]


def test_r_gm_distance_ratio_without_repeats():
    goals = torch.tensor([[1, 0, 2]])
    r = goal_matcher_reward(AGENTS, GOALS, goals, ALIVE)
    d_h = 3.0
    d_m = 2 * 2**0.5 + 1.0
    assert r[0, 0].item() == pytest.approx(-(1 - d_h / d_m), rel=1e-5)
    assert r[0, 1].item() == pytest.approx(-(1 - d_h / d_m), rel=1e-5)
    assert r[0, 2].item() == 0.0


def test_r_gm_dead_agents_get_nothing_and_do_not_count_as_repeats():
    alive = torch.tensor([[True, False, True]])
    r = goal_matcher_reward(AGENTS, GOALS, torch.tensor([[0, 0, 2]]), alive)
    assert r.tolist() == [[0.0, 0.0, 0.0]]


def test_r_gm_rejects_bad_goals():
    with pytest.raises(ValueError, match="goals"):
        goal_matcher_reward(AGENTS, GOALS, torch.tensor([[0.0, 1.0, 2.0]]), ALIVE)


def test_executor_reward_terms():
    pos = torch.tensor([[[0.0, 0.0], [3.0, 0.0]]])
    goal = torch.tensor([[[0.1, 0.0], [3.0, 2.0]]])
    coll = torch.tensor([[0, 2]])
    alive = torch.tensor([[True, True]])
    r = executor_reward(pos, goal, coll, alive, reach=0.15, world_size=8.0, alpha=1.0, beta=2.0, gamma=0.5)
    assert r[0, 0].item() == pytest.approx(1.0 - 2.0 * 0.1 / 4.0)
    assert r[0, 1].item() == pytest.approx(-2.0 * 2.0 / 4.0 - 0.5 * 2)
    assert executor_reward(pos, goal, coll, ~alive, 0.15, 8.0).tolist() == [[0.0, 0.0]]


def test_complete_bonus():
    from masp_lite.algos.rewards import complete_bonus
    dist = torch.tensor([[0.1, 2.0, 0.15]])
    assert complete_bonus(dist, 0.15).tolist() == [[1.0, 0.0, 0.0]]             # the reach itself is out
    assert complete_bonus(dist, 0.15, torch.tensor([[False, True, True]])).tolist() == [[0.0, 0.0, 0.0]]


def test_the_min_max_reference_for_r_gm_is_gone():
    """Tried and not kept (docs/research-log.md): R_GM's reference is the Hungarian one, on distances or squares."""
    a = torch.tensor([[[0.0, 0.0], [0.0, 2.0]]])
    g = torch.tensor([[[3.0, 3.0], [2.0, 3.0]]])
    alive = torch.ones(1, 2, dtype=torch.bool)
    with pytest.raises(TypeError):
        goal_matcher_reward(a, g, torch.tensor([[0, 1]]), alive, cost="bottleneck")
    with pytest.raises(ValueError, match="gm_reference"):
        RewardConfig(gm_reference="bottleneck")


def test_a_crash_mid_rollout_ends_the_agents_return():
    """Agent 1 crashes during step 1 (alive at steps 0-1, gone from step 2): its step 1 bootstraps
    nothing and no advantage flows back across it; agent 0 flies on. Hand-computed GAE."""
    from masp_lite.algos.masp_trainer import terminal_not_done
    g, lam = 0.9, 0.8
    alive = torch.tensor([[True, True], [True, True], [True, False], [True, False]]).unsqueeze(1)  # (T, B=1, N=2)
    r = torch.tensor([[1.0, 0.5], [2.0, -3.0], [0.0, 7.0], [1.0, 7.0]]).unsqueeze(1)
    v = torch.tensor([[0.5, 0.2], [1.0, 0.4], [1.5, 9.0], [2.0, 9.0]]).unsqueeze(1)  # dead steps hold junk
    adv, ret = gae(r, v, torch.zeros(1, 2), g, lam, not_done=terminal_not_done(alive))
    d1 = -3.0 - 0.4                                      # the crash step: delta = r - V, nothing after it
    d0 = 0.5 + g * 0.4 - 0.2
    torch.testing.assert_close(adv[:2, 0, 1], torch.tensor([d0 + g * lam * d1, d1]))
    a = torch.zeros(())                                  # agent 0: plain GAE to the end (bootstrap 0)
    expect = []
    for t in reversed(range(4)):
        nxt = v[t + 1, 0, 0] if t < 3 else 0.0
        a = r[t, 0, 0] + g * nxt - v[t, 0, 0] + g * lam * a
        expect.insert(0, float(a))
    torch.testing.assert_close(adv[:, 0, 0], torch.tensor(expect))
    torch.testing.assert_close(ret, adv + v)
    assert terminal_not_done(torch.ones(5, 2, 3, dtype=torch.bool)).eq(1).all()   # fixed teams: nothing cut
