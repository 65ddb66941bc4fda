"""Metrics, rollouts and ``evaluate`` — how every number is measured (nothing here knows the repository).

* :mod:`.metrics` — SR, Steps, CR (``success_rate``, ``steps``, ``collision_rate``) on an
  :class:`EpisodeLog`, as the paper's section "Metrics" defines them;
* :mod:`.rollouts` — ``rollout`` (episodes of a policy, decision time only) and
  ``contact_breakdown``;
* :mod:`.evaluate` — ``evaluate``: a method over seeds × episodes, the JSON record;
* :mod:`.tables` — records as tables (text, markdown, LaTeX).

The paper's numbers, its tables from the committed records and its claims are the
reproduction room's (:mod:`masp_lite.reproduction`).
"""
from .evaluate import MAX_ENVS, evaluate
from .metrics import EpisodeLog, collision_rate, reached_target, steps, success_rate
from .rollouts import CONTACT_KINDS, contact_breakdown, rollout, rollout_timings
from .tables import format_table

__all__ = ["EpisodeLog", "success_rate", "steps", "collision_rate", "reached_target", "rollout", "rollout_timings",
           "contact_breakdown", "CONTACT_KINDS", "evaluate", "format_table", "MAX_ENVS"]
