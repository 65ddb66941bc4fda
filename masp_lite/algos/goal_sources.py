"""The goal sources that stand in for a trained Goal Matcher (``NetConfig.goal_matcher``), in training and acting.

MASP's trainer (:class:`~masp_lite.algos.masp_trainer.MASPTrainer`) samples goals from its Goal
Matcher and its policy (:class:`~masp_lite.policies.masp.MASPPolicy`) decodes them; the
ablations and baselines that train no Goal Matcher take theirs from one of these sources,
beside the paper's path (:func:`goal_source` picks it, once):

* ``random`` ("MASP w. RG", :class:`RandomGoals`): distinct random goals when the episode starts,
  redrawn only when the team changes (or at every call with ``resample``);
* ``hungarian`` (``h-mappo``, a drone curriculum stage, and the policies' ``decode="hungarian"``
  diagnostic, :class:`HungarianGoals`): the Hungarian assignment every global step;
* ``none`` (``mappo``, ``darl1n``, :class:`NoGoals`): no goals; the executor sees every landmark
  and the team shares a coverage reward (:func:`coverage_reward`) in place of R_CAE.

A source is called ``source(obs, goals, mask, generator) -> goals`` with the goals held now
(``None`` before the first) and the landmarks allowed (``mask`` (B, M) or ``None``); a policy calls it
every global step, training through :meth:`train`, which keeps each source's own timing. With a
varying team, landmarks already reached count for SR, so goals are drawn among the rest.
"""
from __future__ import annotations

import torch

from ..nets.decoding import DECODERS, random_goals
from .team import hungarian_goals

__all__ = ["GoalSource", "RandomGoals", "HungarianGoals", "NoGoals", "SOURCES", "DECODES", "goal_source",
           "coverage_reward"]

#: A policy's ``decode`` settings: the Goal Matcher's decodings, and the Hungarian diagnostic (:func:`goal_source`).
DECODES = (*DECODERS, "hungarian")


class GoalSource:
    """Goals for the executor without a trained Goal Matcher: ``source(obs, goals, mask, generator) -> goals``.

    ``resample`` is random goals' option (drawn again at every call)."""

    def __init__(self, resample: bool = False):
        self.resample, self.drawn_for = bool(resample), None

    def __call__(self, obs: dict, goals, mask, generator: torch.Generator):
        raise NotImplementedError

    def train(self, t: int, obs: dict, goals, generator: torch.Generator, global_step: int, varying: bool):
        """The goals of training's step ``t``: new ones every ``global_step`` steps, among the landmarks not
        reached yet (any, once every one is)."""
        if t % global_step:
            return goals
        mask = ~obs["reached"] | obs["reached"].all(-1, keepdim=True) if varying else None
        return self(obs, goals, mask, generator)


class RandomGoals(GoalSource):
    """"MASP w. RG": distinct random goals, drawn again only when the team changes (every call with ``resample``)."""

    def __call__(self, obs: dict, goals, mask, generator: torch.Generator):
        if self.resample or goals is None or not torch.equal(obs["alive"], self.drawn_for):
            self.drawn_for = obs["alive"].clone()
            return random_goals(obs["alive"], obs["landmark_pos"].shape[1], generator, mask)
        return goals

    def train(self, t: int, obs: dict, goals, generator: torch.Generator, global_step: int, varying: bool):
        """Asked at every step, so a team change redraws at once; among the landmarks not reached yet."""
        return self(obs, goals, ~obs["reached"] if varying else None, generator)


class HungarianGoals(GoalSource):
    """The Hungarian assignment (:func:`~masp_lite.algos.team.hungarian_goals`) of the allowed landmarks."""

    def __call__(self, obs: dict, goals, mask, generator: torch.Generator | None = None):
        return hungarian_goals(obs["agent_pos"], obs["landmark_pos"], obs["alive"], mask)


class NoGoals(GoalSource):
    """No goals (``None``): the goal-free baselines' executor sees every landmark instead."""

    def __call__(self, obs: dict, goals, mask, generator: torch.Generator | None = None):
        return None


#: ``NetConfig.goal_matcher`` -> its source; the learned Goal Matchers (``graph``, ``mlp``) are not here.
SOURCES = {"random": RandomGoals, "hungarian": HungarianGoals, "none": NoGoals}


def goal_source(goal_matcher: str, decode: str | None = None, resample: bool = False):
    """The source of the networks' ``goal_matcher`` setting, or ``None``: their own Goal Matcher picks the goals.

    ``decode="hungarian"`` (the policies' diagnostic) gives the Hungarian goals to networks that
    have a Goal Matcher; ``resample`` redraws random goals at every call."""
    if goal_matcher not in SOURCES and decode == "hungarian":
        goal_matcher = "hungarian"
    return SOURCES[goal_matcher](resample) if goal_matcher in SOURCES else None


def coverage_reward(agent_pos, landmark_pos, agent_collisions, alive, reach: float, world_size: float,
                    alpha: float = 1.0, beta: float = 1.0, gamma: float = 1.0) -> torch.Tensor:
    """The goal-free baselines' reward (``mappo``, ``darl1n``), (B, N), in MPE simple_spread's style.

    With no goals there is no per-agent target: the team shares simple_spread's coverage
    terms, and each agent pays for its own contacts. Scaled like R_CAE so that the same
    coefficients (``RewardConfig``) mean the same::

        R^k = alpha * (fraction of landmarks covered)
              - beta * mean_l min_a dist(l, a) / (world_size / 2)      (alive agents a)
              - gamma * (agent k's contacts)

    A landmark is covered when an alive agent is within ``reach`` of it. Dropped agents get 0.
    """
    d = torch.cdist(landmark_pos, agent_pos).masked_fill(~alive.unsqueeze(1), float("inf"))   # (B, M, N)
    nearest = d.min(-1).values.clamp(max=2 * world_size)                                      # no agent: far
    team = alpha * (nearest < reach).to(agent_pos.dtype).mean(-1) - beta * nearest.mean(-1) / (world_size / 2)
    r = team.unsqueeze(-1) - gamma * agent_collisions.to(agent_pos.dtype)
    return torch.where(alive, r, torch.zeros_like(r))
