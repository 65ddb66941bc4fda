"""Training curves: read a run's ``progress.csv``, find the shipped weights' history, plot it.

A training run (:func:`masp_lite.training.train`) writes one ``progress.csv`` row per
iteration: environment steps, wall-clock, the training episodes' SR / Steps / CR (sampled
actions), both levels' mean rewards, losses and entropies, and — every ``eval_every``
iterations — the deterministic evaluation (``eval_sr``, ``eval_steps``, ``eval_cr``; empty
cells in the other rows). These functions are what chapter 06 uses to look at a run:

* :func:`read_progress` — the file as columns of floats (NaN where a cell is empty);
* :func:`last_evaluation` — the last row that has an evaluation;
* :func:`training_history` — the history of the shipped weights of a scenario (every
  training stage, oldest first, with its curve), read from ``results/training/`` of a
  source checkout; ``None`` when the package is installed without that folder;
* :func:`plot_progress` — SR, Steps, CR and both rewards against environment steps.

Why columns of floats: a curve is plotted and compared as an array, and NaN keeps the
evaluation columns aligned with the iterations (``np.isnan`` finds the evaluated rows).
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from ..weights import HERE, base_scenario, read_manifest

__all__ = ["read_progress", "last_evaluation", "training_history", "plot_progress", "REPO_ROOT"]

#: The source checkout's root (``masp_lite/weights/`` -> two levels up): manifest entries name
#: their training history relative to it.
REPO_ROOT = HERE.parents[1]


def read_progress(path) -> dict[str, np.ndarray]:
    """``progress.csv`` at ``path`` as ``{column: float array}``, one entry per iteration.

    Empty cells (the evaluation columns between evaluations) are NaN. A missing file, a
    file without a header or rows, or a cell that is not a number is one ``ValueError``.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"read_progress: expected an existing progress.csv, got {str(path)!r}")
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
        fields = reader.fieldnames or []
    if not fields or not rows:
        raise ValueError(f"read_progress: {path.name} has no rows (expected a header and one row per iteration)")
    columns = {}
    for key in fields:
        try:
            columns[key] = np.array([float(r[key]) if r[key] not in ("", None) else np.nan for r in rows])
        except ValueError:
            raise ValueError(f"read_progress: {path.name}, column {key!r}: expected numbers") from None
    return columns


def last_evaluation(columns: dict) -> dict | None:
    """``{"iteration", "env_steps", "sr", "steps", "cr"}`` of the last evaluated row, or ``None``."""
    done = np.flatnonzero(~np.isnan(columns["eval_sr"]))
    if not len(done):
        return None
    i = done[-1]
    return {"iteration": int(columns["iteration"][i]), "env_steps": int(columns["env_steps"][i]),
            **{k: float(columns[f"eval_{k}"][i]) for k in ("sr", "steps", "cr")}}


def training_history(scenario: str, root=None) -> dict | None:
    """The training history of the shipped weights for ``scenario``, or ``None`` if it is not here.

    The shipped manifest entry (:func:`masp_lite.weights.read_manifest`) names the history
    manifest (``results/training/SCENARIO-seed0.manifest.json``) relative to ``root``, the
    repository root by default. Returned: that manifest, with every stage's ``progress``
    replaced by the absolute path of its curve (``None`` where the file is missing). No
    shipped weights for the scenario is a ``ValueError``; a missing history (an installed
    package without ``results/``) is ``None``.
    """
    name = base_scenario(scenario)
    entry = read_manifest().get(name)
    if entry is None:
        raise ValueError(f"training_history: no shipped weights for {name!r}; expected one of "
                         f"{sorted(read_manifest())}")
    path = Path(REPO_ROOT if root is None else root) / entry.get("history", "")
    if not entry.get("history") or not path.is_file():
        return None
    history = json.loads(path.read_text())
    for stage in history.get("stages", []):
        curve = path.parent / stage["progress"] if stage.get("progress") else None
        stage["progress"] = curve if curve is not None and curve.is_file() else None
    return history


def plot_progress(columns: dict, title: str = "", baseline: dict | None = None, baseline_label: str = "h-greedy"):
    """One figure of training curves against environment steps; returns the figure.

    Three panels (SR ↑, Steps ↓, CR ↓) show the training episodes (sampled actions) and the
    periodic deterministic evaluation; ``baseline`` (``{"sr", "steps", "cr"}`` means, e.g.
    h-greedy's) adds a dashed line, labelled ``baseline_label``, to each. A fourth panel shows the mean rewards of both
    levels, R_GM (eq. 1) and R_CAE (eq. 5). Call ``plt.show()`` (or let the notebook show it).
    """
    import matplotlib.pyplot as plt

    x = columns["env_steps"]
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.2))
    for ax, (key, label) in zip(axes, [("sr", "SR ↑"), ("steps", "Steps ↓"), ("cr", "CR ↓")]):
        ax.plot(x, columns[f"train_{key}"], alpha=0.5, label="training (sampled)")
        evaluated = ~np.isnan(columns[f"eval_{key}"])
        if evaluated.any():
            ax.plot(x[evaluated], columns[f"eval_{key}"][evaluated], "o-", label="evaluation (deterministic)")
        if baseline is not None and baseline.get(key) is not None:
            ax.axhline(baseline[key], color="k", ls="--", lw=1, label=baseline_label)
        ax.set(title=label, xlabel="environment steps")
    axes[0].legend(fontsize=8)
    axes[3].plot(x, columns["gm_reward"], label="R_GM (eq. 1)")
    axes[3].plot(x, columns["cae_reward"], label="R_CAE (eq. 5)")
    axes[3].set(title="mean rewards", xlabel="environment steps")
    axes[3].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return fig
