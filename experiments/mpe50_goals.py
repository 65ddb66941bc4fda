"""How far the Goal Matcher is from its references at N = 50: one executor, four goal sources.

Usage (from the repository root)::

    python -m experiments.mpe50_goals --checkpoints results/training/mpe-20-seed1.pt [--seeds 100 101 102]
        [--episodes 100] [--scenario mpe-50]

For each weights file, the executor is driven to the goals of (a) its own Goal Matcher
(``masp`` as evaluated), (b) the Hungarian assignment on distances, (c) on squared
distances, (d) the min-max (bottleneck) assignment — every global step, as the Goal
Matcher would. (b)-(d) bound what training the Goal Matcher towards that reference can buy
with this executor; the gap between (a) and them is the Goal Matcher's share. It also
prints how often the Goal Matcher's greedy goals equal each reference's, per agent, on the
episodes of (a). Validation layouts only (evaluation seeds 100+).
"""
from __future__ import annotations

import argparse

import numpy as np
import torch

from masp_lite.algos.assignment import hungarian
from masp_lite.algos.team import bottleneck
from masp_lite.envs import make
from masp_lite.evaluation.metrics import steps
from masp_lite.evaluation.rollouts import rollout
from masp_lite.policies.masp import MASPPolicy

REFERENCES = {"distance": lambda o: hungarian(o["agent_pos"], o["landmark_pos"], o["alive"], None, 1.0),
              "squared": lambda o: hungarian(o["agent_pos"], o["landmark_pos"], o["alive"], None, 2.0),
              "bottleneck": lambda o: bottleneck(o["agent_pos"], o["landmark_pos"], o["alive"], None)}


class ReferenceGoals(MASPPolicy):
    """The executor of a MASP weights file, driven to a reference assignment's goals."""

    METHOD = "masp"

    def __init__(self, world, checkpoint, reference, seed=0):
        super().__init__(world, checkpoint=checkpoint, seed=seed, any_scenario=True)
        self.reference = reference

    def act(self, obs):
        due = (obs["t"] % self.global_step == 0) if self.goals is not None else None
        if self.goals is None or bool(due.any()):
            new = REFERENCES[self.reference](obs)
            self.goals = new if self.goals is None else torch.where(due.unsqueeze(-1), new, self.goals)
        B, N = obs["alive"].shape
        perm = torch.rand(B, N, generator=self.generator).argsort(-1)
        return self._pick(self.nets.cae_logits(self.nets.cae_inputs(obs, self.goals, perm)))


class Agreement(MASPPolicy):
    """The Goal Matcher as evaluated, counting how often its goals equal each reference's."""

    METHOD = "masp"

    def __init__(self, world, checkpoint, seed=0):
        super().__init__(world, checkpoint=checkpoint, seed=seed, any_scenario=True)
        self.same = {k: [0, 0] for k in REFERENCES}

    def act(self, obs):
        decided = self.goals is None or bool((obs["t"] % self.global_step == 0).any())
        out = super().act(obs)
        if decided:
            for k, f in REFERENCES.items():
                ref = f(obs)
                self.same[k][0] += int(((ref == self.goals) & obs["alive"]).sum())
                self.same[k][1] += int(obs["alive"].sum())
        return out


def measure(scenario, checkpoint, seeds, episodes):
    rows = {}
    for name in ["own", *REFERENCES]:
        st, agree = [], None
        for s in seeds:
            world = make(scenario, num_envs=min(episodes, 100), seed=s)
            pol = Agreement(world, checkpoint, seed=s) if name == "own" else ReferenceGoals(world, checkpoint, name, s)
            log, _ = rollout(world, pol, episodes, seed=s)
            st.append(steps(log).double().numpy())
            if name == "own":
                agree = {k: (agree or {}).get(k, 0.0) + v[0] / v[1] / len(seeds) for k, v in pol.same.items()}
        rows[name] = (float(np.concatenate(st).mean()), agree)
    return rows


def validation_parser(doc: str) -> argparse.ArgumentParser:
    """The options of the N = 50 validation scripts: weights files, scenario, validation seeds, episodes."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    p.add_argument("--checkpoints", nargs="+", required=True)
    p.add_argument("--scenario", default="mpe-50")
    p.add_argument("--seeds", nargs="+", type=int, default=[100, 101, 102])
    p.add_argument("--episodes", type=int, default=100)
    return p


def main(argv=None):
    a = validation_parser(__doc__).parse_args(argv)
    torch.set_num_threads(1)
    print(f"{a.scenario}, seeds {a.seeds} x {a.episodes}: Steps with each goal source")
    for ck in a.checkpoints:
        rows = measure(a.scenario, ck, a.seeds, a.episodes)
        agree = rows["own"][1]
        print(f"{ck}: " + "  ".join(f"{k} {v[0]:.2f}" for k, v in rows.items())
              + "  | GM = reference: " + "  ".join(f"{k} {v:.3f}" for k, v in agree.items()))


if __name__ == "__main__":
    main()
