"""Turning the Goal Matcher's per-agent scores into goals when acting: independent or conflict-free.

The paper's Goal Matcher gives every agent ``k`` a categorical ``S_intra^k`` over the goals
(eq. 4) and says agent ``k`` "selects the goal with the highest matching score"; ``R_GM``
(eq. 1) punishes two agents choosing one goal. Read literally, each agent decides alone
(:func:`independent_goals`). Measured on ``mpe-20`` (evaluation seed 0, 100 episodes):
a Goal Matcher trained with independent sampling left several agents on one landmark,
SR 0.59, against 0.98 for the same networks decoded without conflicts; the shipped
weights (trained with the sequential draw, :mod:`masp_lite.nets.goal_draw`) score SR 0.68 decoded independently and
1.00 conflict-free. We therefore decode **conflict-free** by
default, a choice the paper leaves open (it never states how ties between agents are
broken), and keep the literal rule as ``decode="independent"`` for comparison:

* **acting greedily** (evaluation, :func:`joint_argmax`): the assignment of distinct goals
  to the alive agents that minimises ``sum_k (-log S_intra^k(g_k))^2``. This is scipy's
  ``linear_sum_assignment`` on the squared ``-log S_intra``, one call per world (the solver
  the Hungarian reference uses, here on learned scores instead of distances). Squaring
  keeps any agent from being left with a goal it scores poorly: Steps waits for the last
  landmark, so one agent sent to a goal it barely chose costs more than several small
  compromises. The unsquared sum (``power=1``, the most likely distinct assignment) needs
  more Steps on validation layouts (evaluation seeds 100-102 x 100, same weights): mpe-50
  50.13 against 46.89 squared (training seed 0), mpe-20 24.93 / 27.85 / 24.74 against
  24.10 / 25.94 / 23.82 (seeds 0-2), drone-20 343 against 325; mpe-5, mpe-20to10 and
  mpe-50to20 within 1 % (research log, "the Goal Matcher's decoding");
* **sampling** (training): distinct goals drawn agent by agent, each from the goals not yet
  taken (:func:`~masp_lite.nets.goal_draw.sequential_sample`, with the masks' rules used here
  too: dropped agents take no goal and block none, ``goal_mask`` marks the goals that may be
  chosen).
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment

from .goal_draw import MASKED, allowed_goals, sequential_sample

__all__ = ["DECODERS", "independent_goals", "random_goals", "joint_argmax"]

DECODERS = ("joint", "independent")
"""``joint``: conflict-free, squared costs (default); ``independent``: every agent alone, duplicates allowed."""


def random_goals(alive: torch.Tensor, num_goals: int, generator: torch.Generator,
                 goal_mask: torch.Tensor | None = None) -> torch.Tensor:
    """Distinct goals drawn uniformly at random without replacement (B, N): "MASP w. RG".

    :func:`~masp_lite.nets.goal_draw.sequential_sample` with equal logits, so an agent left with nothing (more alive
    agents than allowed goals) and dropped agents are treated alike."""
    B, N = alive.shape
    logits = torch.zeros(B, N, num_goals, device=alive.device)
    return sequential_sample(logits.cpu(), alive.cpu(), generator,
                             None if goal_mask is None else goal_mask.cpu())[0].to(alive.device)


def independent_goals(logits: torch.Tensor, goal_mask: torch.Tensor | None = None) -> torch.Tensor:
    """The paper's literal rule: every agent takes its own highest-scoring allowed goal."""
    return logits.masked_fill(~allowed_goals(goal_mask, logits).unsqueeze(1), MASKED).argmax(-1)


def joint_argmax(logits: torch.Tensor, alive: torch.Tensor, goal_mask: torch.Tensor | None = None,
                 power: float = 2.0) -> torch.Tensor:
    """Distinct goals minimising the summed ``(-log S) ** power`` of the alive agents, per world (B, N).

    Solved by ``linear_sum_assignment`` on ``(-log_softmax(logits)) ** power`` over the alive
    agents and allowed goals (``power=2``: the policies' decoding; ``power=1``: the most likely
    distinct assignment, kept for comparison). Alive agents
    left without a goal (more of them than allowed goals) and dropped agents take their own
    best allowed goal.
    """
    allowed = allowed_goals(goal_mask, logits)
    fallback = independent_goals(logits, allowed)
    cost = (-torch.log_softmax(logits.masked_fill(~allowed.unsqueeze(1), MASKED), -1)).detach().cpu().numpy()
    if power != 1.0:
        cost = cost.astype(np.float64) ** power
    am, gm = alive.cpu().numpy(), allowed.cpu().numpy()
    out = fallback.cpu().numpy().copy()
    for b in range(cost.shape[0]):  # scipy solves one matrix at a time
        rows, cols = np.flatnonzero(am[b]), np.flatnonzero(gm[b])
        if len(rows) == 0:
            continue
        r, c = linear_sum_assignment(cost[b][np.ix_(rows, cols)])
        out[b, rows[r]] = cols[c]
    return torch.from_numpy(out).to(logits.device)
