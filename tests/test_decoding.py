"""Goal decoding: conflict-free sampling and argmax, and the log-probabilities PPO re-evaluates."""
import itertools

import pytest
import torch

from masp_lite.algos.assignment import hungarian
from masp_lite.nets.decoding import independent_goals, joint_argmax
from masp_lite.nets.goal_draw import MASKED, conditional_logits, sequential_sample, taken_before


def _distinct(goals, alive):
    return all(len(set(g[a].tolist())) == int(a.sum()) for g, a in zip(goals, alive))


def test_sequential_sample_gives_alive_agents_distinct_goals_and_matching_log_probs():
    g = torch.Generator().manual_seed(0)
    logits = torch.randn(64, 7, 9) * 3
    alive = torch.rand(64, 7, generator=g) > 0.2
    goals, logp, rank = sequential_sample(logits, alive, g)
    assert _distinct(goals, alive)
    assert sorted(rank[0].tolist()) == list(range(7))
    again = torch.log_softmax(conditional_logits(logits, goals, rank, alive), -1)
    torch.testing.assert_close(torch.gather(again, -1, goals.unsqueeze(-1)).squeeze(-1), logp)


def test_first_drawer_samples_its_own_categorical():
    g = torch.Generator().manual_seed(1)
    logits = torch.tensor([[[2.0, 0.0, -1.0], [0.0, 0.0, 0.0]]]).expand(4000, 2, 3).contiguous()
    goals, _, rank = sequential_sample(logits, torch.ones(4000, 2, dtype=torch.bool), g)
    first = rank[:, 0] == 0
    freq = torch.bincount(goals[first, 0], minlength=3).float() / first.sum()
    torch.testing.assert_close(freq, torch.softmax(logits[0, 0], -1), atol=0.03, rtol=0)


def test_taken_before_ignores_dead_agents_and_later_agents():
    goals = torch.tensor([[0, 0, 1]])
    rank = torch.tensor([[2, 0, 1]])
    alive = torch.tensor([[True, False, True]])
    t = taken_before(goals, rank, alive, 3)
    assert t[0, 0].tolist() == [False, True, False]   # agent 2 (rank 1) took goal 1; agent 1 is dead
    assert not t[0, 1].any() and not t[0, 2].any()


def test_joint_argmax_with_power_1_is_the_most_likely_distinct_assignment():
    torch.manual_seed(2)
    logits = torch.randn(5, 4, 4)
    alive = torch.ones(5, 4, dtype=torch.bool)
    got = joint_argmax(logits, alive, power=1.0)
    logp = torch.log_softmax(logits, -1)
    for b in range(5):
        best = max(itertools.permutations(range(4)), key=lambda p: sum(logp[b, k, p[k]] for k in range(4)))
        assert got[b].tolist() == list(best)


def test_joint_argmax_minimises_the_summed_squared_negative_log_scores():
    torch.manual_seed(2)
    logits = 2 * torch.randn(40, 4, 4)
    alive = torch.ones(40, 4, dtype=torch.bool)
    got = joint_argmax(logits, alive)
    logp = torch.log_softmax(logits, -1).double()
    perms = list(itertools.permutations(range(4)))
    for b in range(40):
        assert got[b].tolist() == list(min(perms, key=lambda p: sum(logp[b, k, p[k]] ** 2 for k in range(4))))
    assert not torch.equal(got, joint_argmax(logits, alive, power=1.0))  # the squares decide differently somewhere


def test_joint_argmax_respects_masks_and_runs_out_of_goals_gracefully():
    logits = torch.zeros(1, 3, 4)
    logits[0, :, 0] = 5.0  # everyone prefers goal 0
    alive = torch.tensor([[True, True, False]])
    mask = torch.tensor([[True, False, True, True]])
    got = joint_argmax(logits, alive, mask)
    assert _distinct(got, alive) and set(got[0, :2].tolist()) <= {0, 2, 3} and 0 in got[0, :2].tolist()
    one = torch.tensor([[False, False, True, False]])          # two alive agents, one allowed goal
    assert got.new_tensor([2, 2]).tolist() == joint_argmax(logits, alive, one)[0, :2].tolist()
    none = torch.zeros(1, 4, dtype=torch.bool)                 # nothing allowed: everything is
    assert _distinct(joint_argmax(logits, alive, none), alive)


def test_independent_goals_allows_duplicates():
    logits = torch.zeros(1, 3, 4)
    logits[0, :, 2] = 1.0
    assert independent_goals(logits).tolist() == [[2, 2, 2]]
    assert conditional_logits(logits, torch.tensor([[2, 2, 2]]), torch.tensor([[0, 1, 2]]),
                              torch.ones(1, 3, dtype=torch.bool))[0, 1, 2] == MASKED


@pytest.mark.parametrize("decode", ["joint", "independent", "hungarian"])
def test_policy_decoders(decode):
    from masp_lite.envs import make
    from masp_lite.nets.masp import MASPNets
    from masp_lite.policies.masp import MASPPolicy
    torch.manual_seed(0)
    w = make("mpe-5", num_envs=4, seed=0)
    pol = MASPPolicy.from_nets(w, MASPNets(), decode=decode)
    obs = w.reset(seed=0)
    pol.act(obs)
    if decode == "joint":
        assert _distinct(pol.goals, obs["alive"])
    if decode == "hungarian":  # the diagnostic: exactly the Hungarian reference's goals
        assert torch.equal(pol.goals, hungarian(obs["agent_pos"], obs["landmark_pos"], obs["alive"]))
    for bad in ("greedy", "squared"):  # "squared" was an option until it became the joint decoding itself
        with pytest.raises(ValueError, match="decode"):
            MASPPolicy.from_nets(w, MASPNets(), decode=bad)


def test_hungarian_diagnostic_on_a_shrinking_team():
    """With more alive agents than unreached landmarks every agent still gets a goal."""
    from masp_lite.envs import make
    from masp_lite.nets.masp import MASPNets
    from masp_lite.policies.masp import MASPPolicy
    torch.manual_seed(0)
    w = make("mpe-20to10", num_envs=2, seed=0, num_agents=6, team_after=3, world_size=3.0)
    pol = MASPPolicy.from_nets(w, MASPNets(), decode="hungarian")
    obs = w.reset(seed=0)
    pol.reset(obs)
    for _ in range(w.horizon):
        obs, _ = w.step(pol.act(obs))
        assert bool((pol.goals >= 0).all()) and bool((pol.goals < 6).all())
