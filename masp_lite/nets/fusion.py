"""Group Information Fusion (paper, section "Coordinated Action Executor").

For each agent ``k`` the other agents are split into groups, each group plus ``k`` becomes
a fully connected subgraph (edges 1), a GCN updates the nodes of every subgraph, and
``k``'s updated feature is averaged over its groups. This keeps the network's input
small (groups of ``N_g`` = 3) while every agent still hears about every other one.

:func:`group_division` — the paper's rule: agent ``k`` joins every group; the others, in a
random order, are cut into groups of ``N_g - 1``; if they do not divide evenly, agents
from the start of the random order (i.e. random agents) join a second group to fill the
last one. With fewer than ``N_g - 1`` others the single group is smaller. The random
order is one permutation per world (``perm`` (B, N)), so storing ``perm`` is enough to
rebuild the exact groups later (PPO recomputes log-probabilities from it).

:func:`gcn_layer` — Kipf & Welling's layer ``H' = ReLU(D^-1/2 (A + I) D^-1/2 H W)``. On a
fully connected subgraph with unit edges every node receives the mean of the group, so
one layer is what the paper's description supports (a second would see identical nodes);
``GroupInformationFusion(layers=...)`` still allows more.

Everything is vectorized over worlds, agents and groups. With one layer (the paper's, and
every shipped network) :class:`masp_lite.nets.kernels.OneLayerFusion` computes the same numbers
a few worlds (or, past a few hundred agents, a slice of one world's agents) at a time, from the CPU
cache; the general path below serves more layers and gradients into the pair features.
Dropped agents (``alive`` False) are removed from every subgraph (no edges), and a group
whose other members are all dropped does not count in the mean.

Why hand-written: a GCN on thousands of 3-node graphs is one batched matrix product;
graph libraries (PyG) would add a heavy dependency for it.
"""
from __future__ import annotations

import math

import torch
from torch import nn

from .encoders import mlp

__all__ = ["group_division", "gcn_layer", "GroupInformationFusion", "random_permutation"]


def random_permutation(batch: int, num_agents: int, generator: torch.Generator | None = None,
                       device="cpu") -> torch.Tensor:
    """One uniformly random order of the agents per world: a long tensor (batch, num_agents)."""
    return torch.rand(batch, num_agents, generator=generator).argsort(dim=-1).to(device)


def group_division(perm: torch.Tensor, group_size: int = 3) -> torch.Tensor:
    """The paper's group division for every agent of every world.

    ``perm`` (B, N): a random order of the agents per world (see :func:`random_permutation`);
    or (B, N, N): one order per agent (row ``k`` for agent ``k``).
    Returns a long tensor (B, N, G, n) of agent indices with ``G = ceil((N - 1) / m)``
    groups of ``n = m + 1`` members, ``m = min(group_size - 1, N - 1)``; entry
    ``[b, k, g, 0]`` is ``k`` itself (k joins every group), the others of agent ``k`` are
    ``perm[b]`` without ``k``, cut in order. Example, 5 agents, identity order, N_g = 3::

        >>> group_division(torch.arange(5)[None], 3)[0, 0].tolist()
        [[0, 1, 2], [0, 3, 4]]
        >>> group_division(torch.arange(4)[None], 3)[0, 0].tolist()   # 3 others: agent 1 twice
        [[0, 1, 2], [0, 3, 1]]
    """
    if isinstance(group_size, bool) or not isinstance(group_size, int) or group_size < 2:
        raise ValueError(f"group_size: expected an int >= 2, got {group_size!r}")
    if perm.dim() not in (2, 3) or (perm.dim() == 3 and perm.shape[1] != perm.shape[2]):
        raise ValueError(f"perm: expected a (B, N) or (B, N, N) tensor, got shape {tuple(perm.shape)}")
    B, N = perm.shape[:2]
    ids = torch.arange(N, device=perm.device)
    if N == 1:
        return ids.view(1, 1, 1, 1).expand(B, 1, 1, 1).clone()
    m = min(group_size - 1, N - 1)
    full = perm.unsqueeze(1).expand(B, N, N) if perm.dim() == 2 else perm
    at = (full == ids.view(1, N, 1)).to(torch.uint8).argmax(-1) if perm.dim() == 3 else perm.argsort(-1)  # k's place
    G = math.ceil((N - 1) / m)
    pad = G * m - (N - 1)
    # the order without k (positions from k's on read one further), then, when uneven, its first agents again
    i = torch.cat([ids[:N - 1], ids[:pad]]).expand(B, N, -1)
    groups = torch.empty(B, N, G, m + 1, dtype=perm.dtype, device=perm.device)
    groups[..., 1:] = torch.gather(full, 2, i + (i >= at.unsqueeze(-1))).view(B, N, G, m)
    groups[..., 0] = ids.view(1, N, 1)
    return groups


def gcn_layer(h: torch.Tensor, adj: torch.Tensor, linear: nn.Module, activation=torch.relu) -> torch.Tensor:
    """One graph-convolution layer ``act(D^-1/2 (A + I) D^-1/2 H W)`` on batched small graphs.

    ``h`` (..., n, F) node features, ``adj`` (..., n, n) edge weights without self loops
    (1 for an edge, 0 for none), ``linear`` the weight ``W`` (F -> F'). Self loops are
    added here, so an isolated node keeps ``act(h W)``.
    """
    n = adj.shape[-1]
    a = adj + torch.eye(n, dtype=adj.dtype, device=adj.device)
    d = a.sum(-1).rsqrt()
    a_hat = d.unsqueeze(-1) * a * d.unsqueeze(-2)
    return activation(a_hat @ linear(h))


class GroupInformationFusion(nn.Module):
    """Agent ``k``'s feature fused over all its groups (B, N, L).

    ``forward(pair_features, groups, alive)``:

    * ``pair_features`` (B, N, N, F): row ``[b, k, j]`` describes agent ``j`` as seen from
      agent ``k`` (relative position and velocity, see
      :func:`masp_lite.nets.masp.pair_features`); the node of ``k`` itself is ``[b, k, k]``;
    * ``groups`` (B, N, G, n) from :func:`group_division`;
    * ``alive`` (B, N) bool.

    Nodes are embedded (Linear + ReLU, F -> L), each subgraph runs ``layers`` GCN layers, and
    ``k``'s node (index 0 of each group) is averaged over the groups that have at least
    one alive other member (over all groups when none has). ``kernel``: one layer on pair features that need
    no gradient runs :class:`masp_lite.nets.kernels.OneLayerFusion` (:func:`~masp_lite.nets.kernels.use_kernels`).
    """

    def __init__(self, in_features: int, width: int = 32, layers: int = 1, kernel: bool = True):
        super().__init__()
        self.kernel, self.embed = kernel, mlp([in_features, width], last_activation=True)
        self.gcn = nn.ModuleList(nn.Linear(width, width) for _ in range(layers))

    def forward(self, pair_features: torch.Tensor, groups: torch.Tensor, alive: torch.Tensor) -> torch.Tensor:
        B, N, G, n = groups.shape
        flat = groups.reshape(B, N, G * n)
        kernel = len(self.gcn) == 1 and self.kernel and not pair_features.requires_grad
        if kernel and bool(alive.all()):  # every member alive: no masks, every group counts (no N^2 gathers)
            member, w = None, torch.ones(B, N, G, dtype=pair_features.dtype, device=pair_features.device)
        else:
            member = torch.gather(alive.unsqueeze(1).expand(B, N, N), 2, flat).view(B, N, G, n).clone()
            member[..., 0] = True                                       # k is always in its groups
            valid = member[..., 1:].any(-1) if n > 1 else member[..., 0]
            w = valid.to(pair_features.dtype)
            w = torch.where(w.sum(-1, keepdim=True) > 0, w, torch.ones_like(w))
        if kernel:
            # Only k's row of the one layer is needed; with unit edges it is the mean over the
            # group's members (see masp_lite.nets.kernels.OneLayerFusion).
            from .kernels import OneLayerFusion
            others = None if member is None or bool(member[..., 1:].all()) else member[..., 1:]
            embed, gcn = self.embed[0], self.gcn[0]
            return OneLayerFusion.apply(pair_features, groups, others, w / w.sum(-1, keepdim=True),
                                         embed.weight, embed.bias, gcn.weight, gcn.bias)
        h = self.embed(pair_features)                               # (B, N, N, L)
        L = h.shape[-1]
        m = member.to(h.dtype)
        hg = torch.gather(h, 2, flat.unsqueeze(-1).expand(B, N, G * n, L)).view(B, N, G, n, L)
        adj = m.unsqueeze(-1) * m.unsqueeze(-2)
        adj = adj * (1 - torch.eye(n, dtype=h.dtype, device=h.device))  # edges 1 between members
        for layer in self.gcn:
            hg = gcn_layer(hg, adj, layer)
        mine = hg[..., 0, :]
        return (mine * w.unsqueeze(-1)).sum(2) / w.sum(-1, keepdim=True)
