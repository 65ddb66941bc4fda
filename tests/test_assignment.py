"""Hungarian assignment: optimality against brute force, rectangular cases, masks, seeds."""
import itertools

import numpy as np
import pytest
import torch

from masp_lite.algos.assignment import assignment_cost, hungarian
from masp_lite.algos.team import hungarian_random_subset


def brute_force(a, g, power=1.0):
    """Least total distance (to ``power``) over all injective maps of the smaller side into the larger."""
    n, m = len(a), len(g)
    d = np.linalg.norm(a[:, None] - g[None], axis=-1) ** power
    if n <= m:
        return min(sum(d[i, p[i]] for i in range(n)) for p in itertools.permutations(range(m), n))
    return min(sum(d[p[j], j] for j in range(m)) for p in itertools.permutations(range(n), m))


@pytest.mark.parametrize("n,m,d", [(4, 4, 2), (5, 5, 3), (3, 5, 2), (5, 3, 2), (1, 4, 3)])
def test_matches_brute_force(n, m, d):
    rng = np.random.default_rng(n * 10 + m)
    a = torch.from_numpy(rng.normal(size=(6, n, d)))
    g = torch.from_numpy(rng.normal(size=(6, m, d)))
    out = hungarian(a, g)
    assert out.shape == (6, n) and out.dtype == torch.long
    cost = assignment_cost(a, g, out)
    for b in range(6):
        assigned = out[b][out[b] >= 0]
        assert len(set(assigned.tolist())) == len(assigned) == min(n, m)  # distinct goals
        assert cost[b].item() == pytest.approx(brute_force(a[b].numpy(), g[b].numpy()), rel=1e-9)
    if n > m:
        assert ((out == -1).sum(1) == n - m).all()  # extra agents get no goal


def test_masks_exclude_agents_and_goals():
    a = torch.tensor([[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]])
    g = torch.tensor([[[0.0, 0.1], [1.0, 0.1], [2.0, 0.1]]])
    out = hungarian(a, g, agent_mask=torch.tensor([[True, False, True]]),
                    goal_mask=torch.tensor([[False, True, True]]))
    assert out.tolist() == [[1, -1, 2]]
    # nothing available -> everyone -1
    none = hungarian(a, g, goal_mask=torch.zeros(1, 3, dtype=torch.bool))
    assert none.tolist() == [[-1, -1, -1]]


def test_random_subset_draws_subset_then_assigns():
    rng = np.random.default_rng(0)
    a = torch.from_numpy(rng.uniform(size=(50, 2, 2)))
    g = torch.from_numpy(rng.uniform(size=(50, 6, 2)))
    gmask = torch.ones(50, 6, dtype=torch.bool)
    gmask[:, 0] = False  # goal 0 reached: never drawn
    out1 = hungarian_random_subset(a, g, goal_mask=gmask, generator=torch.Generator().manual_seed(3))
    out2 = hungarian_random_subset(a, g, goal_mask=gmask, generator=torch.Generator().manual_seed(3))
    assert torch.equal(out1, out2)  # same generator state, same answer
    assert (out1 >= 1).all() and (out1[:, 0] != out1[:, 1]).all()
    # random, not the least-cost subset: some worlds must differ from plain Hungarian
    assert (out1 != hungarian(a, g, goal_mask=gmask)).any()
    # each subset is drawn uniformly: over many worlds every available goal gets used
    assert set(out1.flatten().tolist()) == {1, 2, 3, 4, 5}
    # with a numpy generator too; more agents than goals behaves as hungarian
    many = hungarian_random_subset(g, a, generator=np.random.default_rng(1))
    assert torch.equal(many, hungarian(g, a))


def test_device_dtype_and_bad_input():
    a = torch.zeros(2, 3, 2, dtype=torch.float32)
    g = torch.ones(2, 3, 2, dtype=torch.float32)
    assert assignment_cost(a, g, hungarian(a, g)).dtype == torch.float32
    with pytest.raises(ValueError, match="point dimension"):
        hungarian(a, torch.zeros(2, 3, 3))
    with pytest.raises(ValueError, match="3-d"):
        hungarian(torch.zeros(3, 2), g)
    with pytest.raises(ValueError, match="agent_mask"):
        hungarian(a, g, agent_mask=torch.ones(2, 4, dtype=torch.bool))
    with pytest.raises(ValueError, match="generator"):
        hungarian_random_subset(a, g, generator=0)
    with pytest.raises(ValueError, match="goal indices"):
        assignment_cost(a, g, torch.full((2, 3), 3))


def test_distance_matrix_is_the_batched_cost():
    from scipy.spatial.distance import cdist

    from masp_lite.algos.assignment import distance_matrix
    rng = np.random.default_rng(5)
    a, g = rng.normal(size=(3, 4, 3)), rng.normal(size=(3, 6, 3))
    d = distance_matrix(a, g)
    assert d.shape == (3, 4, 6)
    for b in range(3):
        np.testing.assert_allclose(d[b], cdist(a[b], g[b]))


@pytest.mark.parametrize("n,m", [(5, 5), (3, 5), (5, 3)])
def test_power_two_matches_brute_force(n, m):
    rng = np.random.default_rng(7 + n + m)
    a, g = torch.from_numpy(rng.normal(size=(5, n, 2))), torch.from_numpy(rng.normal(size=(5, m, 2)))
    out = hungarian(a, g, power=2)
    cost = assignment_cost(a, g, out, power=2)
    for b in range(5):
        assert cost[b].item() == pytest.approx(brute_force(a[b].numpy(), g[b].numpy(), 2.0), rel=1e-9)


def test_squared_cost_shortens_the_longest_trip():
    """Agent 1 sits on goal 0: total distance sends agent 0 on the long trip, squares do not."""
    a = torch.tensor([[[0.0, 0.0], [1.0, 0.0]]])
    g = torch.tensor([[[1.0, 0.0], [2.0, 0.3]]])
    assert hungarian(a, g).tolist() == [[1, 0]]            # 2.022 + 0 < 1 + 1.044
    assert hungarian(a, g, power=2).tolist() == [[0, 1]]   # 1 + 1.09 < 4.09 + 0
    assert assignment_cost(a, g, torch.tensor([[0, 1]]), power=2).item() == pytest.approx(1 + 1.09)
    for bad in (0, -1.0, float("inf"), True, "2"):
        with pytest.raises(ValueError, match="power"):
            hungarian(a, g, power=bad)


def test_bottleneck_minimises_the_longest_trip_then_the_total():
    import itertools

    from masp_lite.algos.team import bottleneck
    g = torch.Generator().manual_seed(0)
    for n, m in ((5, 5), (4, 6), (6, 4)):
        a, goals = torch.rand(20, n, 2, generator=g), torch.rand(20, m, 2, generator=g)
        got = bottleneck(a, goals)
        for b in range(20):
            d = torch.cdist(a[b], goals[b]).double()
            k = min(n, m)
            best = None  # brute force over every assignment of k agents to k goals
            for rows in itertools.combinations(range(n), k):
                for cols in itertools.permutations(range(m), k):
                    trips = d[list(rows), list(cols)]
                    key = (float(trips.max()), float(trips.sum()))
                    best = key if best is None or key < best else best
            mine = [(i, int(j)) for i, j in enumerate(got[b]) if j >= 0]
            assert len(mine) == k and len({j for _, j in mine}) == k
            trips = torch.stack([d[i, j] for i, j in mine])
            assert abs(float(trips.max()) - best[0]) < 1e-9 and abs(float(trips.sum()) - best[1]) < 1e-9
    assert (bottleneck(a, goals, agent_mask=torch.zeros(20, 6, dtype=torch.bool)) == -1).all()


def test_sequential_keeps_goals_until_reached_and_hands_on_the_rest():
    from masp_lite.algos.team import sequential
    a = torch.tensor([[[0.0, 0.0], [5.0, 0.0]]])
    g = torch.tensor([[[0.1, 0.0], [5.1, 0.0], [9.0, 0.0], [-3.0, 0.0]]])
    avail = torch.ones(1, 4, dtype=torch.bool)
    first = sequential(a, g, None, avail)
    assert first.tolist() == [[0, 1]]                                      # Hungarian over all four
    a2 = torch.tensor([[[8.0, 0.0], [-2.0, 0.0]]])                         # both moved far away
    assert sequential(a2, g, None, avail, current=first).tolist() == [[0, 1]]  # goals kept, not re-solved
    reached = torch.tensor([[True, False, False, False]])
    nxt = sequential(a2, g, None, ~reached, current=first)
    assert nxt.tolist() == [[2, 1]]               # agent 0 reached its goal: the nearest goal nobody holds
    gone = torch.tensor([[True, False]])
    assert sequential(a2, g, gone, ~reached, current=nxt).tolist() == [[2, -1]]
