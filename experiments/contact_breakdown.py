"""One line of ``contacts/SCENARIO.jsonl``: a method's CR split four ways (evaluation seed 0, 100 episodes).

Usage (from the repository root)::

    python results/masp/contacts/breakdown.py SCENARIO METHOD [CHECKPOINT] [--weights LABEL]

See :func:`masp_lite.eval.contact_breakdown` for the four kinds. ``LABEL`` names the
weights in the record (e.g. "first recipe", "shipped"); a checkpoint is loaded with
``any_scenario=True`` so mpe-20 weights can be probed on other maps.
"""
import argparse
import json

import torch

from masp_lite.envs import make
from masp_lite.eval import contact_breakdown
from masp_lite.methods import make_policy

p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
p.add_argument("scenario")
p.add_argument("method")
p.add_argument("checkpoint", nargs="?")
p.add_argument("--weights", default=None, help="label of the weights, stored in the record")
a = p.parse_args()
torch.set_num_threads(1)
opts = {"checkpoint": a.checkpoint, "any_scenario": True} if a.checkpoint else {}
world = make(a.scenario, num_envs=100, seed=0)
rec = {"scenario": a.scenario, "method": a.method, **opts}
if a.weights:
    rec["weights"] = a.weights
rec.update(contact_breakdown(world, make_policy(a.method, world, **opts), 100, seed=0))
print(json.dumps(rec))
