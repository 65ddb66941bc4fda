"""The paper's metrics — SR, Steps, CR — defined once, on an :class:`EpisodeLog`.

The paper's metrics (section "Metrics") are defined once, here, on an :class:`EpisodeLog`:

* :func:`success_rate` — **SR**, "the average ratio of landmarks reached by the agents to
  the total landmarks per episode". A landmark is reached when an alive agent is within
  ``r_agent + r_landmark``. Fixed teams: the fraction of landmarks covered *at the end* of
  the episode (the task is to cover all at once). Varying teams: the fraction *ever*
  reached ("the ratio of the landmarks reached during the navigation", section
  "Varying Team Sizes").
* :func:`steps` — **Steps**, "the average timesteps required to achieve a target Success
  Rate" (the target is SR = 1): per episode, the first ``t`` at which the SR-so-far is 1
  (fixed: every landmark covered at that same step; varying: every landmark reached by
  then). ``t`` counts environment steps taken, so ``t = 0`` (solved at spawn) is allowed
  and means zero steps were required. An episode that never gets there counts as the
  horizon. When *no* episode gets there the paper prints a backslash; :func:`evaluate`
  reports ``null`` and :func:`format_table` prints ``\\``.
* :func:`collision_rate` — **CR**, "the average ratio of collision occurrences to the total
  number of environmental steps per episode": collision events (agent–agent and
  agent–obstacle pairs in contact after a step, alive agents only) summed over the episode
  and divided by its number of steps ``T``.

For fixed teams SR and Steps can disagree: an episode may cover every landmark at step 12
(Steps 12) and lose one to a collision before the end (SR 0.8). Both are reported as the
paper defines them.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

__all__ = ["EpisodeLog", "success_rate", "steps", "collision_rate", "reached_target"]


@dataclass
class EpisodeLog:
    """What the metrics need from a batch of ``E`` episodes of ``T`` steps (``T`` = horizon).

    Index ``t`` of the ``T + 1`` axis is the state after ``t`` steps (``t = 0``: at reset).
    """

    covered: torch.Tensor
    """(E, T + 1, L) bool — landmark covered by an alive agent at step t."""
    reached: torch.Tensor
    """(E, T + 1, L) bool — landmark reached at some step <= t."""
    collisions: torch.Tensor
    """(E, T) long — collision events after step t + 1 (contact pairs)."""
    alive: torch.Tensor
    """(E, T + 1, N) bool — agents in the team at step t."""
    varying: bool
    """True when the team size changes (SR and Steps then use ``reached``)."""
    horizon: int
    """Steps per episode; the Steps value of an episode that never reaches SR 1."""

    def __post_init__(self):
        cov, rea, col, alive = self.covered, self.reached, self.collisions, self.alive
        shapes = [tuple(x.shape) if torch.is_tensor(x) else type(x).__name__ for x in (cov, rea, col, alive)]
        ok = all(torch.is_tensor(x) for x in (cov, rea, col, alive)) and cov.dim() == 3 and \
            rea.shape == cov.shape and col.shape == cov.shape[:1] + (cov.shape[1] - 1,) and \
            alive.dim() == 3 and alive.shape[:2] == cov.shape[:2] and \
            cov.dtype == rea.dtype == alive.dtype == torch.bool and not col.dtype.is_floating_point
        if not ok:
            raise ValueError("EpisodeLog: expected bool covered/reached (E, T+1, L), integer collisions "
                             f"(E, T) and bool alive (E, T+1, N); got shapes {shapes}")
        if isinstance(self.horizon, bool) or not isinstance(self.horizon, int) or self.horizon < 1:
            raise ValueError(f"EpisodeLog.horizon: expected a positive int, got {self.horizon!r}")

    @classmethod
    def cat(cls, logs: list[EpisodeLog]) -> EpisodeLog:
        """Episodes of several logs (same horizon and team rule) in one log."""
        if not logs:
            raise ValueError("EpisodeLog.cat: expected at least one log")
        first = logs[0]
        if any(lg.varying != first.varying or lg.horizon != first.horizon for lg in logs):
            raise ValueError("EpisodeLog.cat: expected logs with the same horizon and varying flag")
        fields = ("covered", "reached", "collisions", "alive")
        return cls(*(torch.cat([getattr(lg, f) for lg in logs]) for f in fields),
                   varying=first.varying, horizon=first.horizon)


def _solved(log: EpisodeLog) -> torch.Tensor:
    """(E, T + 1) bool: the SR-so-far is 1 at step t (fixed: all covered; varying: all reached)."""
    return (log.reached if log.varying else log.covered).all(dim=-1)


def success_rate(log: EpisodeLog) -> torch.Tensor:
    """SR per episode, float64 (E,): final coverage (fixed teams) or ever reached (varying)."""
    final = log.reached[:, -1] if log.varying else log.covered[:, -1]
    return final.double().mean(dim=-1)


def steps(log: EpisodeLog) -> torch.Tensor:
    """Steps per episode, float64 (E,): first t in [0, T] with SR-so-far 1, else the horizon."""
    solved = _solved(log)
    T1 = solved.shape[1]
    t = torch.arange(T1, device=solved.device).expand_as(solved)
    first = torch.where(solved, t, torch.full_like(t, T1)).min(dim=1).values
    return torch.where(first < T1, first, torch.full_like(first, log.horizon)).double()


def reached_target(log: EpisodeLog) -> torch.Tensor:
    """(E,) bool: the episode reached SR 1 at some step (used for the Steps backslash)."""
    return _solved(log).any(dim=1)


def collision_rate(log: EpisodeLog) -> torch.Tensor:
    """CR per episode, float64 (E,): collision events summed over the episode / its T steps."""
    return log.collisions.sum(dim=1).double() / log.collisions.shape[1]
