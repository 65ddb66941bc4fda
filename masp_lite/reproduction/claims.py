"""Which result is better, metric by metric — and the paper's MASP numbers to compare with.

The course never writes "MASP beats h-greedy" in advance: it computes the comparison
from :func:`~masp_lite.evaluation.evaluate` records, the same way for every pair.

* :func:`better` — which of two means is better on one metric (higher SR, lower Steps and
  CR). A Steps mean of ``None`` means no episode ever covered every landmark (the paper's
  backslash): worse than any number;
* :func:`verdict` — one line per metric: both means and which one is better;
* :data:`PAPER_MASP` — MASP's means as the paper reports them (its tables "MPE" and "MPE,
  varying team size", from :mod:`.paper`);
* :func:`against_paper` — :func:`verdict` of a record against :data:`PAPER_MASP` for its
  scenario, on the metrics the paper reports there.

Both sides may be ``evaluate`` records (``{"sr": {"mean": ..., "std": ...}, ...}``) or
plain means (``{"sr": 0.99, ...}``).
"""
from __future__ import annotations

from .paper import PAPER

__all__ = ["PAPER_MASP", "HIGHER_IS_BETTER", "better", "verdict", "against_paper"]

#: MASP's means in the paper (:data:`masp_lite.reproduction.paper.PAPER`), by scenario and metric.
PAPER_MASP = {sc: {k: v[0] for k, v in cells.items() if v[0] is not None}
              for table in ("mpe", "mpe-varying") for (sc, method), cells in PAPER[table].items() if method == "masp"}

#: Metric -> whether a higher mean is better.
HIGHER_IS_BETTER = {"sr": True, "steps": False, "cr": False}
_LABELS = {"sr": "SR", "steps": "Steps", "cr": "CR"}


def _mean(result: dict, key: str):
    value = result[key]
    return value.get("mean") if isinstance(value, dict) else value


def better(metric: str, a, b, tol: float = 1e-9) -> str:
    """``"a"``, ``"b"``, ``"tie"`` (within ``tol``) or ``"neither"`` (both ``None``) for two means."""
    if metric not in HIGHER_IS_BETTER:
        raise ValueError(f"better: expected a metric in {sorted(HIGHER_IS_BETTER)}, got {metric!r}")
    if a is None and b is None:
        return "neither"
    if a is None or b is None:
        return "b" if a is None else "a"
    if abs(a - b) < tol:
        return "tie"
    return "a" if (a > b) == HIGHER_IS_BETTER[metric] else "b"


def verdict(rec_a: dict, rec_b: dict, name_a: str = "MASP", name_b: str = "h-greedy",
            metrics=("sr", "steps", "cr")) -> list[str]:
    """One line per metric: ``"SR   : MASP   0.990   h-greedy   1.000   -> h-greedy better"``."""
    show = lambda v: "  never" if v is None else f"{v:7.3f}"  # noqa: E731
    words = {"a": f"{name_a} better", "b": f"{name_b} better", "tie": "a tie",
             "neither": "neither ever covers every landmark"}
    lines = []
    for key in metrics:
        a, b = _mean(rec_a, key), _mean(rec_b, key)
        lines.append(f"{_LABELS[key]:5s}: {name_a} {show(a)}   {name_b} {show(b)}   -> {words[better(key, a, b)]}")
    return lines


def against_paper(record: dict, name: str = "ours") -> list[str]:
    """:func:`verdict` of ``record`` against the paper's MASP on its scenario ([] if none reported)."""
    paper = PAPER_MASP.get(record["scenario"])
    if paper is None:
        return []
    return verdict(record, paper, name, "paper", metrics=[k for k in ("sr", "steps", "cr") if k in paper])
