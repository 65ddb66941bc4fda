"""Metrics, rollouts, ``evaluate`` and the paper's tables — how every number is measured.

* :mod:`.metrics` — SR, Steps, CR (``success_rate``, ``steps``, ``collision_rate``) on an
  :class:`EpisodeLog`, as the paper's section "Metrics" defines them;
* :mod:`.rollouts` — ``rollout`` (episodes of a policy, decision time only) and
  ``contact_breakdown``;
* :mod:`.evaluate` — ``evaluate``: a method over seeds × episodes, the JSON record;
* :mod:`.tables` — records as the paper's tables (text, markdown, LaTeX);
* :mod:`.claims` — which of two records is better, metric by metric, and the paper's
  MASP numbers to compare with (``verdict``, ``against_paper``, ``PAPER_MASP``);
* :mod:`.paper` — the paper's numbers (``PAPER``), typed in once;
* :mod:`.reproduce` — the paper's tables and its MPE claims from the committed records
  (``python -m masp_lite reproduce``).
"""
from .evaluate import MAX_ENVS, evaluate
from .metrics import EpisodeLog, collision_rate, reached_target, steps, success_rate
from .rollouts import CONTACT_KINDS, contact_breakdown, rollout, rollout_timings
from .tables import format_table

__all__ = ["EpisodeLog", "success_rate", "steps", "collision_rate", "reached_target", "rollout", "rollout_timings",
           "contact_breakdown", "CONTACT_KINDS", "evaluate", "format_table", "MAX_ENVS"]
