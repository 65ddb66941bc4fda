"""The networks of the paper's ablations (section "Ablation Studies"): one graph of MASP
replaced by an MLP over the same inputs.

* :class:`GoalMatcherMLP` — "GM w.o. Graph": for agent ``k``, an MLP over the
  concatenated map-normalised positions of every agent (agent ``k`` first, then the others
  in index order) and every goal -> logits over the goals: the paper's "concatenated
  position information of all agents and goals for agent k, with the position information
  of agent k listed first". It gets positions only, not the graph version's nearest-distance
  node inputs or its two distance channels per pair (:func:`~masp_lite.nets.features.gm_inputs`):
  given those, an MLP matched the graphs (docs/research-log.md, 2026-12-02), since they
  already say which agent is closest to each goal.
* :class:`FusionMLP` — "CAE w.o. Graph": the executor's Group Information Fusion replaced
  by an MLP over agent ``k``'s view of every agent (:func:`~masp_lite.nets.features.pair_features`:
  relative position, distance, relative velocity; ``k`` first, then the others), -> the
  same ``width`` features. The goal and obstacle embeddings and the head are MASP's.

Both take a fixed number of inputs, so they are built for one team size (``team_size``)
and refuse any other with one clear error: train and evaluate them at N = 20 only.
"""
from __future__ import annotations

import torch
from torch import nn

from .encoders import mlp

__all__ = ["GoalMatcherMLP", "FusionMLP", "agent_first"]


def agent_first(n: int, device=None) -> torch.Tensor:
    """(n, n) long: row ``k`` is ``[k, 0, 1, ..., k-1, k+1, ..., n-1]``."""
    idx = torch.arange(n, device=device)
    others = idx.expand(n, n)[~torch.eye(n, dtype=torch.bool, device=device)].view(n, n - 1)
    return torch.cat([idx.unsqueeze(1), others], dim=1)


def _check_size(name: str, team_size: int, got: int) -> None:
    if got != team_size:
        raise ValueError(f"{name}: built for {team_size} agents (an MLP over every agent has a fixed input size), "
                         f"got {got}; train and evaluate it at the team size it was built for")


class GoalMatcherMLP(nn.Module):
    """"GM w.o. Graph": ``forward(agent_x, goal_x, dist, alive, goal_mask=None) -> logits`` (B, N, M).

    Same signature as :class:`~masp_lite.nets.masp.GoalMatcher` (it reads the positions in
    ``agent_x`` and ``goal_x`` and ignores the rest); ``team_size`` agents and as many goals.
    Dropped agents' positions are zeroed."""

    def __init__(self, width: int = 32, team_size: int = 20, dims: int = 2):
        super().__init__()
        self.team_size, self.dims = team_size, dims
        n = team_size
        self.net = mlp([n * dims + n * dims, 4 * width, 4 * width, n])
        self.register_buffer("order", agent_first(n), persistent=False)

    def forward(self, agent_x, goal_x, dist, alive, goal_mask=None):
        B, N = agent_x.shape[:2]
        _check_size("gm-mlp", self.team_size, N)
        _check_size("gm-mlp (goals)", self.team_size, goal_x.shape[1])
        D = self.dims
        a = agent_x[..., :D] * alive.unsqueeze(-1).to(agent_x.dtype)        # positions / (world_size / 2)
        agents = a[:, self.order].reshape(B, N, -1)                         # row k: agent k first
        x = torch.cat([agents, goal_x[..., :D].reshape(B, 1, -1).expand(B, N, -1)], dim=-1)
        logits = self.net(x)
        if goal_mask is not None:
            logits = logits.masked_fill(~goal_mask.unsqueeze(1), float("-inf"))
        return logits


class FusionMLP(nn.Module):
    """"CAE w.o. Graph": ``forward(pair, groups, alive) -> (B, N, width)``, the Group
    Information Fusion's signature (``groups`` is ignored: there are none)."""

    def __init__(self, in_features: int, width: int = 32, team_size: int = 20):
        super().__init__()
        self.team_size = team_size
        self.net = mlp([team_size * in_features, 4 * width, width], last_activation=True)
        self.register_buffer("order", agent_first(team_size), persistent=False)

    def forward(self, pair: torch.Tensor, groups: torch.Tensor, alive: torch.Tensor) -> torch.Tensor:
        B, N = pair.shape[:2]
        _check_size("cae-mlp", self.team_size, N)
        seen = pair * alive.unsqueeze(1).unsqueeze(-1).to(pair.dtype)       # [b, k, j]: j dropped -> zeros
        rows = torch.gather(seen, 2, self.order.view(1, N, N, 1).expand(B, N, N, pair.shape[-1]))
        return self.net(rows.reshape(B, N, -1))
