"""One line of ``results/mpe/contacts_SCENARIO.jsonl``: a method's CR split four ways (evaluation seed 0, 100 episodes).

Usage (from the repository root)::

    python -m experiments.contact_breakdown SCENARIO METHOD [CHECKPOINT] [--weights LABEL] \
        >> results/mpe/contacts_SCENARIO.jsonl

See :func:`masp_lite.evaluation.contact_breakdown` for the four kinds. ``LABEL`` names the
weights in the record (e.g. "shipped"); a checkpoint is loaded with ``any_scenario=True``
so mpe-20 weights can be probed on other maps.
"""
from __future__ import annotations

import argparse
import json

import torch

from masp_lite.envs import make
from masp_lite.evaluation import contact_breakdown
from masp_lite.policies import make_policy


def record(scenario: str, method: str, checkpoint: str | None = None, weights: str | None = None,
           episodes: int = 100) -> dict:
    """The line for ``method`` on ``scenario``: its options, then the four parts of CR and their total."""
    opts = {"checkpoint": checkpoint, "any_scenario": True} if checkpoint else {}
    world = make(scenario, num_envs=min(episodes, 100), seed=0)
    rec = {"scenario": scenario, "method": method, **opts}
    if weights:
        rec["weights"] = weights
    rec.update(contact_breakdown(world, make_policy(method, world, **opts), episodes, seed=0))
    return rec


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("scenario")
    p.add_argument("method")
    p.add_argument("checkpoint", nargs="?")
    p.add_argument("--weights", default=None, help="label of the weights, stored in the record")
    a = p.parse_args(argv)
    torch.set_num_threads(1)
    print(json.dumps(record(a.scenario, a.method, a.checkpoint, a.weights)))


if __name__ == "__main__":
    main()
