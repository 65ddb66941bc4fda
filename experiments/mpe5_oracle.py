"""Is SR 0.99 reachable on mpe-5 at all? A model-based search that knows the world exactly.

Usage (from the repository root)::

    python -m experiments.mpe5_oracle [--candidates 128] [--noise 0.5]
                                      [--contact-weight 1] [--coverage-weight 0.5]

This is a reference point, not a method of the paper: a centralized planner that reads the
full state of every episode and simulates the future with the world's own ``step``. Each
step it does the following:

1. It assigns goals by the Hungarian algorithm on squared distances, the same reference as R_GM with
   ``gm_reference=squared`` (:func:`masp_lite.algos.assignment.hungarian`).
2. It copies the episode ``K`` times (:func:`copy_state`). Each copy then runs to the end
   of the episode under :func:`arrival_actions`, a simple velocity controller. In copy
   ``i`` each agent's action is replaced by a random one with probability
   ``noise * i / (K - 1)``, so copy 0 is the noise-free controller.
3. It scores each copy at the end of the episode:
   ``10 * covered landmarks - (sum of each landmark's distance to its nearest agent)
   - contact_weight * contacts + coverage_weight * (landmarks covered, summed over the steps)``.
4. It plays the first joint action of the best copy, and repeats the whole search at the next step.

Ties go to the lower copy index, which has less noise.

With ``--per-agent`` each agent searches alone. Agent ``k`` gets its own ``K`` copies, in which
only ``k`` takes random actions and every other agent follows the controller. ``k`` plays the
first action of its best copy. This asks whether lookahead by each agent, with no joint choice
of moves, is enough. It is still not decentralized in what it sees: the score is the team's.
Episodes and evaluation seeds are those of ``evaluate`` (seeds 0 1 2, 100 episodes each).
Steps, SR and CR are computed by :mod:`masp_lite.evaluation`'s own functions.

Written by hand because it needs the world's internal state. A generic planning library would
need the particle world rewritten in its terms.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from masp_lite.algos.assignment import hungarian
from masp_lite.envs import ACTION_DIRECTIONS, PHYSICS, make
from masp_lite.evaluation import EpisodeLog, collision_rate, rollout, steps, success_rate


def arrival_actions(pos: torch.Tensor, vel: torch.Tensor, goal: torch.Tensor, max_speed: float = 2.0) -> torch.Tensor:
    """Per agent, the action whose next velocity is nearest to the velocity that coasts to ``goal``.

    Under the no-op an MPE body coasts ``v * dt / damping`` (0.4 v) before it stops, so the
    wanted velocity is ``(goal - pos) * damping / dt``, capped at ``max_speed`` (MPE's
    terminal speed under a constant push). The next velocity under action ``a`` is
    ``(1 - damping) v + sensitivity * dt / mass * dir_a`` (contacts ignored).
    """
    p = PHYSICS
    want = (goal - pos) * p["damping"] / p["dt"]
    want = want * (max_speed / want.norm(dim=-1, keepdim=True).clamp(min=max_speed))
    dirs = torch.tensor(ACTION_DIRECTIONS, dtype=vel.dtype)
    nxt = (1 - p["damping"]) * vel.unsqueeze(-2) + p["sensitivity"] * p["dt"] / p["mass"] * dirs
    return (nxt - want.unsqueeze(-2)).norm(dim=-1).argmin(-1)


def copy_state(sim, world, reps: int) -> None:
    """Make episode ``e`` of ``world`` the start of episodes ``e * reps ... e * reps + reps - 1`` of ``sim``."""
    sim.set_state(world.get_state(), repeat=reps)


class SearchOracle:
    """Policy interface of :mod:`masp_lite.evaluation` (``reset``, ``act``) around the search above."""

    def __init__(self, world, candidates: int = 128, noise: float = 0.5, contact_weight: float = 1.0,
                 coverage_weight: float = 0.5, seed: int = 0, per_agent: bool = False):
        self.world, self.noise, self.per_agent = world, float(noise), bool(per_agent)
        self.contact_weight, self.coverage_weight = float(contact_weight), float(coverage_weight)
        self.K = int(candidates) * (world.num_agents if per_agent else 1)       # copies per episode
        self.sim = make(world.scenario, num_envs=world.num_envs * self.K, seed=seed)
        self.sim.reset(seed=seed)
        self.generator = torch.Generator().manual_seed(seed)

    def reset(self, obs) -> None:
        pass

    def goals(self, obs) -> torch.Tensor:
        """Each agent's goal (B, N) for the controller: the Hungarian assignment on squared distances."""
        w = self.world
        return hungarian(w.agent_pos, w.landmark_pos, w.alive, None, 2.0)

    def act(self, obs) -> torch.Tensor:
        w, sim, K, g = self.world, self.sim, self.K, self.generator
        B, N = w.num_envs, w.num_agents
        goals = self.goals(obs)
        goal_pos = torch.gather(w.landmark_pos, 1, goals.unsqueeze(-1).expand(B, N, 2)).repeat_interleave(K, 0)
        copy_state(sim, w, K)
        C = K // N if self.per_agent else K                                     # copies per search
        p = (torch.linspace(0, self.noise, C) if C > 1 else torch.zeros(1)).repeat(K // C)
        if self.per_agent:                                      # search k: only agent k is noisy
            p = p.view(N, C, 1) * torch.eye(N).view(N, 1, N)
        p = p.reshape(1, K, -1).expand(B, K, -1).reshape(B * K, -1)
        contacts = torch.zeros(B * K, dtype=torch.float64)
        covered = torch.zeros(B * K, dtype=torch.float64)
        first = None
        for _ in range(int(w.t.max()), w.horizon):
            a = arrival_actions(sim.agent_pos, sim.agent_vel, goal_pos)
            noisy = torch.rand(a.shape, generator=g) < p
            a = torch.where(noisy, torch.randint(0, len(ACTION_DIRECTIONS), a.shape, generator=g), a)
            first = a if first is None else first
            _, info = sim.step(a)
            contacts += info["collisions"]
            covered += info["covered"].sum(-1)
        near = torch.cdist(sim.landmark_pos, sim.agent_pos).min(-1).values.sum(-1)
        score = 10 * sim.covered.sum(-1) - near - self.contact_weight * contacts + self.coverage_weight * covered
        if not self.per_agent:
            best = score.view(B, K).argmax(-1)
            return first.view(B, K, N)[torch.arange(B), best]
        best = score.view(B, N, C).argmax(-1)                                   # (B, N): agent k's best copy
        moves = first.view(B, N, C, N)
        b, k = torch.arange(B).view(B, 1), torch.arange(N).view(1, N)
        return moves[b, k, best, k]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="mpe-5")
    ap.add_argument("--candidates", type=int, default=128)
    ap.add_argument("--noise", type=float, default=0.5)
    ap.add_argument("--contact-weight", type=float, default=1.0)
    ap.add_argument("--coverage-weight", type=float, default=0.5)
    ap.add_argument("--per-agent", action="store_true", help="each agent searches its own moves alone")
    a = ap.parse_args(argv)
    torch.set_num_threads(1)
    start, logs = time.perf_counter(), []
    for seed in (0, 1, 2):
        world = make(a.scenario, num_envs=100, seed=seed)
        oracle = SearchOracle(world, a.candidates, a.noise, a.contact_weight, a.coverage_weight, seed=seed,
                              per_agent=a.per_agent)
        logs.append(rollout(world, oracle, 100, seed)[0])
    log = EpisodeLog.cat(logs)
    sr = success_rate(log).numpy()
    print(f"search oracle on {a.scenario} ({a.candidates} copies{' per agent' if a.per_agent else ''}, "
          f"noise {a.noise}, contact weight "
          f"{a.contact_weight}, coverage weight {a.coverage_weight}): Steps {steps(log).numpy().mean():.2f}, "
          f"SR {sr.mean():.4f}, CR {collision_rate(log).numpy().mean():.3f}, "
          f"missed landmarks {int(np.rint((1 - sr) * log.covered.shape[-1]).sum())} "
          f"of {sr.size * log.covered.shape[-1]} ({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
