"""Batched rollouts that time only the policy's decisions, and where a policy's contacts happen.

:func:`rollout` runs episodes of a policy (:class:`masp_lite.policies.Policy`) on a
batched world and returns the :class:`~masp_lite.evaluation.metrics.EpisodeLog` the
metrics read, with the decision time per step; :func:`contact_breakdown` splits CR into
four kinds of contact.
"""
from __future__ import annotations

import time

import numpy as np
import torch

from .metrics import EpisodeLog

__all__ = ["rollout", "rollout_timings", "contact_breakdown", "CONTACT_KINDS"]


def _sync(device) -> None:
    if torch.device(device).type == "cuda":
        torch.cuda.synchronize(device)


def rollout_timings(world, policy, episodes: int, seed: int | None = None, progress=None, on_step=None):
    """:func:`rollout`, returning every ``act`` call's seconds per world (an array) instead of their mean.

    ``progress`` (a tqdm bar) is advanced once per step.
    """
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected a positive int, got {episodes!r}")
    B, T = world.num_envs, world.horizon
    device = getattr(world, "device", "cpu")
    logs, timings = [], []
    done_eps = 0
    first = True
    while done_eps < episodes:
        obs = world.reset(seed=seed if first else None)  # later batches continue the world's RNG
        first = False
        policy.reset(obs)
        # The episode's log is filled in place: a small tensor kept every step would split the large blocks
        # that the networks free (hundreds of agents: megabytes per step) and grow the heap by about one per step.
        cov, rea, alive = (torch.empty(B, T + 1, *obs[k].shape[1:], dtype=torch.bool, device=obs[k].device)
                           for k in ("covered", "reached", "alive"))
        col = torch.empty(B, T, dtype=torch.long, device=obs["alive"].device)
        cov[:, 0], rea[:, 0], alive[:, 0] = obs["covered"], obs["reached"], obs["alive"]
        keep = min(B, episodes - done_eps)
        for t in range(T):
            _sync(device)
            t0 = time.perf_counter()
            actions = policy.act(obs)
            _sync(device)
            timings.append((time.perf_counter() - t0) / B)
            obs, info = world.step(actions)
            cov[:, t + 1], rea[:, t + 1], alive[:, t + 1] = info["covered"], info["reached"], info["alive"]
            col[:, t] = info["collisions"]
            if on_step is not None:
                on_step(obs, keep)
            if progress is not None:
                progress.update(1)
        logs.append(EpisodeLog(cov[:keep].cpu(), rea[:keep].cpu(), col[:keep].cpu(), alive[:keep].cpu(),
                               varying=bool(world.scenario.varying), horizon=int(T)))
        done_eps += keep
    return EpisodeLog.cat(logs), np.asarray(timings)


def rollout(world, policy, episodes: int, seed: int | None = None, on_step=None):
    """Run ``episodes`` episodes of ``policy`` on the batched ``world``.

    Episodes run ``world.num_envs`` at a time (the last batch is trimmed); the first batch
    starts with ``world.reset(seed=seed)`` and later ones continue the world's generator,
    so the same seed and batch size give the same episodes. Works for any world honouring
    the observation/info contract (particle and drone worlds; actions are passed through
    untouched).

    Returns ``(log, decision_seconds_per_step)``: the :class:`EpisodeLog` and the mean
    wall time of ``policy.act`` per step *of one world* — each call is timed with
    ``time.perf_counter`` (CUDA synchronised around it) and divided by ``num_envs``, the
    worlds it decides for. The environment's own step is not timed. ``on_step(obs, keep)``,
    when given, sees the observation after every step and how many leading worlds of the
    batch are episodes that count (e.g. :func:`contact_breakdown`).
    """
    log, timings = rollout_timings(world, policy, episodes, seed, on_step=on_step)
    return log, float(timings.mean())


CONTACT_KINDS = ("agent-agent, both on landmarks", "agent-agent, en route", "agent-obstacle, on a landmark",
                 "agent-obstacle, en route")
"""The four parts of CR that :func:`contact_breakdown` reports."""


def contact_breakdown(world, policy, episodes: int, seed: int | None = None) -> dict[str, float]:
    """Where a policy's contacts happen on a particle world: CR split four ways.

    Runs ``episodes`` episodes as :func:`rollout` does (same seed, same episodes) and
    counts every contact after every step, as CR does. An agent is *on a landmark* when
    it is within reach of any landmark after the step. An agent–agent contact is "both on
    landmarks" when both agents are, else "en route"; an agent–obstacle contact is "on a
    landmark" when the agent is. Returns the mean contacts per step of each kind
    (:data:`CONTACT_KINDS`) and their sum under ``"total"``, which equals the mean CR.
    """
    sc = world.scenario
    if sc.kind != "particle":
        raise ValueError(f"contact_breakdown: expected a particle world, got scenario {sc.name!r}")
    sums = torch.zeros(len(CONTACT_KINDS), dtype=torch.float64)
    exact = "donot_use_mm_for_euclid_dist"  # the world's own distances, no matmul shortcut

    def count(obs, keep):
        pos, alive = obs["agent_pos"][:keep], obs["alive"][:keep]
        on = (torch.cdist(pos, obs["landmark_pos"][:keep]) <= sc.reach_distance).any(-1) & alive
        aa = torch.triu(torch.cdist(pos, pos, compute_mode=exact) < 2 * sc.agent_radius, diagonal=1)
        aa &= alive.unsqueeze(2) & alive.unsqueeze(1)
        both = on.unsqueeze(2) & on.unsqueeze(1)
        ao = torch.cdist(pos, obs["obstacle_pos"][:keep], compute_mode=exact) < sc.agent_radius + sc.obstacle_radius
        ao &= alive.unsqueeze(2)
        sums.add_(torch.stack([(aa & both).sum(), (aa & ~both).sum(), (ao & on.unsqueeze(2)).sum(),
                               (ao & ~on.unsqueeze(2)).sum()]).double())

    rollout(world, policy, episodes, seed, on_step=count)  # the same batches and seeds as rollout()
    T = world.horizon
    parts = {k: float(v) / (episodes * T) for k, v in zip(CONTACT_KINDS, sums)}
    return {**parts, "total": float(sums.sum()) / (episodes * T)}
