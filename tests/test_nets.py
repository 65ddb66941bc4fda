"""MASP's networks: the paper's equations on small hand-checkable inputs, masks, size invariance."""
import math

import pytest
import torch

from masp_lite.envs import make
from masp_lite.nets.encoders import CrossEncoder, SelfEncoder, node_update, s_inter
from masp_lite.nets.features import obstacle_features, pair_features
from masp_lite.nets.fusion import GroupInformationFusion, gcn_layer, group_division, random_permutation
from masp_lite.nets.masp import MASPNets
from masp_lite.policies.masp import MASPPolicy


def test_s_inter_is_row_softmax_of_query_key_products():
    torch.manual_seed(0)
    q, k = torch.randn(2, 4, 8), torch.randn(2, 4, 8)
    s = s_inter(q, k)
    manual = torch.softmax(torch.einsum("bil,bjl->bij", q, k) / math.sqrt(8), dim=-1)
    torch.testing.assert_close(s, manual)
    torch.testing.assert_close(s.sum(-1), torch.ones(2, 4))


def test_s_inter_ignores_masked_nodes():
    torch.manual_seed(1)
    q, k = torch.randn(1, 5, 4), torch.randn(1, 5, 4)
    mask = torch.tensor([[True, True, False, True, False]])
    s = s_inter(q, k, mask)
    assert torch.all(s[..., ~mask[0]] == 0)
    torch.testing.assert_close(s.sum(-1), torch.ones(1, 5))
    k2 = k.clone()
    k2[0, 2] += 100.0  # a masked node's key cannot change anything
    torch.testing.assert_close(s_inter(q, k2, mask), s)


def test_node_update_matches_equation_3():
    x = torch.tensor([[[1.0, 0.0], [0.0, 2.0]]])
    v = torch.tensor([[[1.0, 1.0], [3.0, -1.0]]])
    s = torch.tensor([[[0.25, 0.75], [1.0, 0.0]]])
    seen = {}

    def fake_mlp(z):
        seen["z"] = z
        return z[..., 2:] * 10

    y = node_update(x, v, s, fake_mlp)
    # node 0 receives 0.25 * v0 + 0.75 * v1 = (2.5, -0.5); node 1 receives v0
    torch.testing.assert_close(seen["z"][0, 0], torch.tensor([1.0, 0.0, 2.5, -0.5]))
    torch.testing.assert_close(y[0, 1], torch.tensor([10.0, 12.0]))


def test_self_encoder_is_permutation_equivariant():
    torch.manual_seed(2)
    enc = SelfEncoder(8)
    x = torch.randn(3, 6, 8)
    perm = torch.randperm(6)
    y, _ = enc(x)
    yp, _ = enc(x[:, perm])
    torch.testing.assert_close(yp, y[:, perm], atol=1e-5, rtol=1e-5)


def test_cross_encoder_scores_are_a_distribution_and_follow_goal_order():
    torch.manual_seed(3)
    ce = CrossEncoder(8)
    ya, yt, d = torch.randn(2, 3, 8), torch.randn(2, 5, 8), torch.rand(2, 3, 5)
    s = ce.scores(ya, yt, d)
    q = ce.query(ya).unsqueeze(2).expand(2, 3, 5, 8)    # eq. 4 written literally: MLP of the concatenation
    k = ce.key(yt).unsqueeze(1).expand(2, 3, 5, 8)
    literal = torch.softmax(ce.score(torch.cat([q, k, d.unsqueeze(-1)], -1)).squeeze(-1), -1)
    torch.testing.assert_close(s, literal)
    torch.testing.assert_close(s.sum(-1), torch.ones(2, 3))
    perm = torch.randperm(5)
    torch.testing.assert_close(ce.scores(ya, yt[:, perm], d[..., perm]), s[..., perm])
    d2 = d.clone()
    d2[0, 0, 1] += 1.0  # the distance input matters
    assert not torch.allclose(ce(ya, yt, d2)[0, 0, 1], ce(ya, yt, d)[0, 0, 1])


def test_cross_encoder_chunked_head_matches_eq4_literally_in_value_and_gradients(monkeypatch):
    """The chunked score head (hand-written backward) against autograd through the concatenation."""
    from masp_lite.nets import kernels
    monkeypatch.setattr(kernels, "SCORE_ROWS", 16)        # several chunks
    torch.manual_seed(5)
    ce = CrossEncoder(6, distance_channels=2).double()
    ya = torch.randn(3, 4, 6, dtype=torch.float64, requires_grad=True)
    yt = torch.randn(3, 5, 6, dtype=torch.float64, requires_grad=True)
    d = torch.rand(3, 4, 5, 2, dtype=torch.float64)
    mask = torch.rand(3, 5) > 0.3
    fast = ce(ya, yt, d, mask)
    q = ce.query(ya).unsqueeze(2).expand(3, 4, 5, 6)
    k = ce.key(yt).unsqueeze(1).expand(3, 4, 5, 6)
    literal = ce.score(torch.cat([q, k, d], -1)).squeeze(-1).masked_fill(~mask.unsqueeze(1), float("-inf"))
    torch.testing.assert_close(fast, literal)
    g = torch.randn(3, 4, 5, dtype=torch.float64)
    inputs = [ya, yt, *ce.parameters()]
    mine = torch.autograd.grad(fast.masked_fill(~mask.unsqueeze(1), 0.0), inputs, g)
    theirs = torch.autograd.grad(literal.masked_fill(~mask.unsqueeze(1), 0.0), inputs, g)
    for a, c in zip(mine, theirs):
        torch.testing.assert_close(a, c)
    assert torch.autograd.gradcheck(lambda a, b: ce(a, b, d), (ya, yt))


@pytest.mark.parametrize("n,ng", [(2, 3), (3, 3), (4, 3), (5, 3), (20, 3), (50, 3), (7, 4), (6, 2)])
def test_group_division_follows_the_paper(n, ng):
    perm = random_permutation(3, n, torch.Generator().manual_seed(n))
    groups = group_division(perm, ng)
    B, N, G, m1 = groups.shape
    m = min(ng - 1, n - 1)
    assert (N, G, m1) == (n, math.ceil((n - 1) / m), m + 1)
    ids = torch.arange(n).view(1, n, 1)
    assert torch.all(groups[..., 0] == ids)                       # k joins every group
    others = groups[..., 1:].reshape(B, N, -1)
    assert not torch.any(others == ids)                           # nobody else is k
    for b in range(B):
        for k in range(N):
            counts = torch.bincount(others[b, k], minlength=n)
            assert counts[k] == 0 and torch.all(counts[torch.arange(n) != k] >= 1)
            assert int((counts - 1).clamp(min=0).sum()) == G * m - (n - 1)   # only the fill-up repeats
            assert torch.all(torch.tensor([len(set(g.tolist())) for g in groups[b, k]]) == m + 1)


def test_group_division_single_agent_and_bad_size():
    assert group_division(torch.zeros(2, 1, dtype=torch.long), 3).shape == (2, 1, 1, 1)
    with pytest.raises(ValueError, match="group_size"):
        group_division(torch.arange(4)[None], 1)


def test_gcn_layer_on_a_fully_connected_group_is_the_group_mean():
    h = torch.tensor([[1.0, 0.0], [0.0, 3.0], [2.0, 3.0]])
    adj = torch.ones(3, 3) - torch.eye(3)
    lin = torch.nn.Linear(2, 2, bias=False)
    with torch.no_grad():
        lin.weight.copy_(torch.tensor([[1.0, 0.0], [0.0, -1.0]]))
    out = gcn_layer(h, adj, lin)
    expect = torch.relu(lin(h.mean(0)))
    torch.testing.assert_close(out, expect.expand(3, 2))
    lone = gcn_layer(h, torch.zeros(3, 3), lin)                     # no edges: own feature only
    torch.testing.assert_close(lone, torch.relu(lin(h)))


def _fusion_by_loops(gif, pair, groups, alive):
    """Reference: agent k's fused feature computed group by group with Python loops."""
    B, N, G, n = groups.shape
    out = torch.zeros(B, N, gif.gcn[0].out_features)
    for b in range(B):
        for k in range(N):
            feats, valid = [], []
            for g in range(G):
                members = [int(j) for j in groups[b, k, g] if int(j) == k or alive[b, j]]
                h = gif.embed(pair[b, k, members])
                adj = torch.ones(len(members), len(members)) - torch.eye(len(members))
                for layer in gif.gcn:
                    h = gcn_layer(h, adj, layer)
                feats.append(h[0])
                valid.append(len(members) > 1)
            use = [f for f, v in zip(feats, valid) if v] or feats
            out[b, k] = torch.stack(use).mean(0)
    return out


def test_group_information_fusion_matches_loops_with_dead_agents():
    torch.manual_seed(4)
    gif = GroupInformationFusion(6, 8)
    two = GroupInformationFusion(6, 8, layers=2)
    pos, vel = torch.randn(2, 6, 2), torch.randn(2, 6, 2)
    pair = pair_features(pos, vel)
    groups = group_division(random_permutation(2, 6, torch.Generator().manual_seed(0)), 3)
    alive = torch.tensor([[True] * 6, [True, False, True, False, False, True]])
    with torch.no_grad():
        fast = gif(pair, groups, alive)
        slow = _fusion_by_loops(gif, pair, groups, alive)
    torch.testing.assert_close(fast, slow, atol=1e-5, rtol=1e-5)
    with torch.no_grad():
        torch.testing.assert_close(two(pair, groups, alive), _fusion_by_loops(two, pair, groups, alive),
                                   atol=1e-5, rtol=1e-5)
    moved = pos.clone()
    moved[1, 1] += 0.3  # a dropped agent's state cannot change the others' features
    with torch.no_grad():
        again = gif(pair_features(moved, vel), groups, alive)
    torch.testing.assert_close(again[1, alive[1]], fast[1, alive[1]])


def test_obstacle_features_nearest_first_and_padding():
    pos = torch.zeros(1, 1, 2)
    obst = torch.tensor([[[0.5, 0.0], [0.0, 0.3], [5.0, 5.0]]])
    f = obstacle_features(pos, obst, 2).view(2, 3)
    torch.testing.assert_close(f[0], torch.tensor([0.0, 0.3, 0.3]))
    torch.testing.assert_close(f[1], torch.tensor([0.5, 0.0, 0.5]))
    pad = obstacle_features(pos, obst[:, :1], 2).view(2, 3)
    torch.testing.assert_close(pad[1], torch.tensor([0.0, 0.0, 1.0]))
    assert obstacle_features(pos, torch.zeros(1, 0, 2), 2).shape == (1, 1, 6)


@pytest.mark.parametrize("scenario,n", [("mpe-5", None), ("mpe-20", None), ("mpe-5", 8), ("mpe-20to10", None)])
def test_networks_run_for_any_team_size(scenario, n):
    torch.manual_seed(5)
    nets = MASPNets()
    over = {} if n is None else {"num_agents": n}
    w = make(scenario, num_envs=3, seed=0, **over)
    obs = w.reset()
    N = w.num_agents
    logits = nets.gm_logits(obs, w.scenario.world_size / 2)
    assert logits.shape == (3, N, N) and torch.isfinite(logits).all()
    goals = logits.argmax(-1)
    inputs = nets.cae_inputs(obs, goals, random_permutation(3, N))
    assert nets.cae_logits(inputs).shape == (3, N, 5)
    assert nets.cae_forward(inputs, obs, w.horizon)[1].shape == (3, N)
    value = nets.gm_value(obs, 1.0, w.horizon)
    assert value.shape == (3, N)
    both = nets.gm_forward(obs, 1.0, w.horizon)  # training's one pass: the same numbers as the two calls
    assert torch.equal(both[0], nets.gm_logits(obs, 1.0)) and torch.equal(both[1], value)


def test_masp_nets_reject_bad_architecture():
    with pytest.raises(ValueError, match="group_size"):
        MASPNets(group_size=1)
    with pytest.raises(ValueError, match="group_order"):  # a setting that was tried and not kept
        MASPNets(group_order="nearest")


def test_group_division_rejects_a_bad_order():
    with pytest.raises(ValueError, match="perm"):
        group_division(torch.zeros(1, 5, 4, dtype=torch.long), 3)


def test_policy_is_seeded_and_respects_dead_agents(tmp_path):
    from masp_lite.weights import save_weights
    torch.manual_seed(6)
    path = tmp_path / "w.pt"
    save_weights(path, MASPNets(), "mpe-20")
    w = make("mpe-20to10", num_envs=2, seed=1)
    runs = []
    for _ in range(2):
        obs = w.reset(seed=3)
        pol = MASPPolicy(w, checkpoint=str(path), seed=7, deterministic=False)
        pol.reset(obs)
        acts = []
        for _ in range(w.scenario.change_step + 2):
            a = pol.act(obs)
            assert a.shape == (2, 20) and a.dtype == torch.long and int(a.min()) >= 0 and int(a.max()) < 5
            assert torch.all(a[~obs["alive"]] == 0)
            acts.append(a)
            obs, _ = w.step(a)
        runs.append(torch.stack(acts))
    assert torch.equal(runs[0], runs[1])


@pytest.mark.parametrize("agents, dead", [(7, False), (7, True), (2, False), (1, False)])
def test_one_layer_fusion_matches_the_general_path_in_value_and_gradients(agents, dead, monkeypatch):
    """The chunked one-layer fusion (hand-written backward) against autograd through gcn_layer."""
    from masp_lite.nets import kernels
    monkeypatch.setattr(kernels, "FUSION_ROWS", 20)  # several chunks even for these small worlds
    torch.manual_seed(3)
    gif = GroupInformationFusion(6, 5).double()
    pos, vel = torch.randn(3, agents, 2, dtype=torch.float64), torch.randn(3, agents, 2, dtype=torch.float64)
    pair = pair_features(pos, vel)
    groups = group_division(random_permutation(3, agents, torch.Generator().manual_seed(1)), 3)
    alive = torch.ones(3, agents, dtype=torch.bool)
    if dead:
        alive[1, [1, 3, 4]] = False
        alive[2, 1:] = False                                   # agent 0 alone: every group empty
    g = torch.randn(3, agents, 5, dtype=torch.float64)
    fast = gif(pair, groups, alive)
    mine = torch.autograd.grad(fast, list(gif.parameters()), g)
    general = gif(pair.clone().requires_grad_(), groups, alive)  # a pair gradient takes the general path
    theirs = torch.autograd.grad(general, list(gif.parameters()), g)
    torch.testing.assert_close(fast, general)
    for a, c in zip(mine, theirs):
        torch.testing.assert_close(a, c)
    others = None if not dead else torch.gather(alive.unsqueeze(1).expand(3, agents, agents), 2,
                                                groups.flatten(2)).view(groups.shape)[..., 1:]
    B, N, G, n = groups.shape
    weight = torch.full((B, N, G), 1.0 / G, dtype=torch.float64)
    assert torch.autograd.gradcheck(
        lambda *p: kernels.OneLayerFusion.apply(pair, groups, others, weight, *p),
        (gif.embed[0].weight, gif.embed[0].bias, gif.gcn[0].weight, gif.gcn[0].bias))


def test_one_layer_fusion_reads_the_nodes_a_gather_reads():
    """The fusion's row numbers (one ``index_select`` per chunk) pick exactly the pair features that the
    literal gathers ``pair[b, k, groups[b, k, g, m]]`` pick, bit for bit."""
    from masp_lite.nets import kernels
    B, N = 4, 6
    pair = pair_features(torch.randn(B, N, 2), torch.randn(B, N, 2))
    groups = group_division(random_permutation(B, N, torch.Generator().manual_seed(2)), 3)
    self_rows, other_rows = kernels.OneLayerFusion._rows(groups)
    rows = pair.reshape(-1, pair.shape[-1])
    F, (G, n) = pair.shape[-1], groups.shape[2:]
    x_self = torch.gather(pair, 2, groups[..., :1, 0].unsqueeze(-1).expand(B, N, 1, F))
    x_oth = torch.gather(pair, 2, groups[..., 1:].reshape(B, N, -1, 1).expand(B, N, G * (n - 1), F))
    assert torch.equal(rows[self_rows].view(B, N, 1, F), x_self)
    assert torch.equal(rows[other_rows].view(B, N, -1, F), x_oth)


@pytest.mark.parametrize("executor", ["attention", "radius"])
@pytest.mark.parametrize("dead", [False, True])
def test_pool_kernel_matches_autograd_in_value_and_gradients(executor, dead, monkeypatch):
    """The chunked pooling kernel of mappo/darl1n (hand-written backward) against plain autograd."""
    from masp_lite.nets import baselines, kernels
    from masp_lite.nets.kernels import use_kernels
    monkeypatch.setattr(kernels, "POOL_ROWS", 30)  # several chunks even for these small worlds
    torch.manual_seed(4)
    agents = 6
    view = (baselines.AttentionPool(6, 5) if executor == "attention" else baselines.RadiusMean(6, 5)).double()
    pos = torch.rand(3, agents, 2, dtype=torch.float64) * 1.5   # some pairs within 1 m, some beyond
    pair = pair_features(pos, torch.randn(3, agents, 2, dtype=torch.float64))
    alive = torch.ones(3, agents, dtype=torch.bool)
    if dead:
        alive[1, [1, 3]] = False
        alive[2, 1:] = False                                    # agent 0 alone: nobody to pool
    g = torch.randn(3, agents, 5, dtype=torch.float64)
    fast = view(pair, None, alive)
    mine = torch.autograd.grad(fast, list(view.parameters()), g, allow_unused=True)
    plain = use_kernels(view, False)(pair, None, alive)
    theirs = torch.autograd.grad(plain, list(view.parameters()), g, allow_unused=True)
    torch.testing.assert_close(fast, plain)
    for a, c in zip(mine, theirs):
        if c is None:  # the score's last bias does not move a softmax: autograd reports no gradient
            assert a is None or torch.count_nonzero(a.abs() > 1e-12) == 0
        else:
            torch.testing.assert_close(a, c)
    if dead:
        assert torch.count_nonzero(fast[2, 0]) == 0
    assert torch.autograd.gradcheck(lambda *p: _pool_with(view, pair, alive, p), tuple(view.parameters()))


def _pool_with(view, pair, alive, params):
    """``view`` evaluated with ``params`` in place of its own (gradcheck perturbs them)."""
    return torch.func.functional_call(view, dict(zip([n for n, _ in view.named_parameters()], params)),
                                      (pair, None, alive))
