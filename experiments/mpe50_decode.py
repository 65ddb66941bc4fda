"""Which conflict-free decoding of the Goal Matcher's scores serves Steps best at N = 50?

Usage (from the repository root)::

    python -m experiments.mpe50_decode --checkpoints masp_lite/weights/mpe-20.pt [--seeds 100 101 102]
        [--episodes 100] [--scenario mpe-50] [--decodes sum squared minmax probability]

The product first decoded greedily by the distinct goals that maximise the summed log-scores
(``sum``: ``linear_sum_assignment`` on ``-log S``). Steps waits for the last landmark, so
one agent sent on a long trip costs the whole episode; decodings that weigh the least
confident agent more might serve Steps better with the same weights:

* ``squared``: ``linear_sum_assignment`` on ``(-log S)^2`` (between sum and min-max; what
  this comparison made the product's ``joint`` decoding);
* ``minmax``: the assignment whose least likely pick is as likely as possible (min-max of
  ``-log S``), ties broken by the summed ``-log S``;
* ``probability``: maximise the summed scores ``S`` (not their logs).

Prints Steps, SR and CR per decoding (validation layouts only: evaluation seeds 100+).
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment

from experiments.mpe50_goals import validation_parser
from masp_lite.envs import make
from masp_lite.evaluation.metrics import collision_rate, steps, success_rate
from masp_lite.evaluation.rollouts import rollout
from masp_lite.policies.masp import MASPPolicy


def minmax_assignment(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of a square or wide cost matrix's min-max assignment, ties broken by the sum."""
    values = np.unique(d)
    lo, hi = 0, len(values) - 1
    while lo < hi:  # the smallest threshold whose edges still hold a full matching
        mid = (lo + hi) // 2
        over = d > values[mid]
        r, c = linear_sum_assignment(over)
        lo, hi = (lo, mid) if not over[r, c].any() else (mid + 1, hi)
    return linear_sum_assignment(np.where(d <= values[lo], d, (np.abs(d).sum() + 1.0) * 2))


COSTS = {"sum": lambda nl: nl, "squared": lambda nl: nl ** 2, "probability": lambda nl: -np.exp(-nl)}


class Decoded(MASPPolicy):
    """MASP with the Goal Matcher's greedy goals chosen by another conflict-free decoding (fixed teams)."""

    METHOD = "masp"

    def __init__(self, world, checkpoint, how, seed=0):
        super().__init__(world, checkpoint=checkpoint, seed=seed, any_scenario=True)
        self.how = how

    def _goals(self, logits, alive, mask):
        nl = (-torch.log_softmax(logits, -1)).numpy().astype(np.float64)
        out = logits.argmax(-1).numpy().copy()
        for b in range(nl.shape[0]):
            rows = np.flatnonzero(alive[b].numpy())
            cost = nl[b][rows]
            r, c = minmax_assignment(cost) if self.how == "minmax" else linear_sum_assignment(COSTS[self.how](cost))
            out[b, rows[r]] = c
        return torch.from_numpy(out)


def main(argv=None):
    p = validation_parser(__doc__)
    p.add_argument("--decodes", nargs="+", default=["sum", "squared", "minmax", "probability"],
                   choices=["sum", "squared", "minmax", "probability"])
    a = p.parse_args(argv)
    if min(a.seeds) < 100:
        raise SystemExit("--seeds: validation layouts only (100 and above)")
    torch.set_num_threads(1)
    print(f"{a.scenario}, seeds {a.seeds} x {a.episodes}: Steps / SR / CR per decoding", flush=True)
    for ck in a.checkpoints:
        for how in a.decodes:
            st, sr, cr = [], [], []
            for s in a.seeds:
                world = make(a.scenario, num_envs=min(a.episodes, 100), seed=s)
                log, _ = rollout(world, Decoded(world, ck, how, seed=s), a.episodes, seed=s)
                st.append(steps(log).double().numpy())
                sr.append(success_rate(log).double().numpy())
                cr.append(collision_rate(log).double().numpy())
            print(f"{ck} {how}: {np.concatenate(st).mean():.2f} / {np.concatenate(sr).mean():.3f} / "
                  f"{np.concatenate(cr).mean():.3f}", flush=True)


if __name__ == "__main__":
    main()
