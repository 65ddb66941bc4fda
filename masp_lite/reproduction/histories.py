"""The kept training histories of a source checkout: ``results/training/``.

Chapters 06, 10 and 11 show how the shipped weights and the ablations' seeds were trained.
Those curves are records of the repository, not package data, so reading them is this
room's; plotting them is :mod:`masp_lite.viz.progress`'s (:func:`~masp_lite.viz.progress.read_progress`,
:func:`~masp_lite.viz.progress.plot_progress`, :func:`~masp_lite.viz.progress.plot_seed_bands`).

* :func:`training_history` — the history of the shipped weights of a scenario (every
  training stage, oldest first, with its curve); ``None`` in an installed copy;
* :func:`kept_curves` — the curves of a recipe's kept training seeds
  (``results/training/FOLDER/``); ``{}`` in an installed copy.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..files import read_bounded
from ..viz.progress import read_progress
from ..weights import base_scenario, read_manifest, shipped_entry
from . import KEPT_DIR, REPO_ROOT

__all__ = ["training_history", "kept_curves"]


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
    entry = shipped_entry(scenario)
    if entry is None:
        raise ValueError(f"training_history: no shipped weights for {name!r}; expected one of "
                         f"{sorted(read_manifest())}")
    path = Path(REPO_ROOT if root is None else root) / entry.get("history", "")
    if not entry.get("history") or not path.is_file():
        return None
    history = json.loads(read_bounded(path, what="kept history"))
    for stage in history.get("stages", []):
        curve = path.parent / stage["progress"] if stage.get("progress") else None
        stage["progress"] = curve if curve is not None and curve.is_file() else None
    return history


def kept_curves(folder: str, scenario: str = "mpe-20", root=None) -> dict[int, dict[str, np.ndarray]]:
    """The curves of a recipe's kept training seeds: ``{seed: read_progress(...)}``.

    ``folder`` is a folder of ``results/training/`` (``"faithful"``, ``"masp-rg"``, ...) holding
    ``SCENARIO-seedK.progress.csv`` (the last stage of each seed, see
    :func:`masp_lite.reproduction.shipping.ship_run`); ``root``: a repository root other than this
    checkout. ``{}`` when there is none (an installed package)."""
    base = (KEPT_DIR if root is None else Path(root) / "results" / "training") / folder
    out = {}
    for path in sorted(base.glob(f"{scenario}-seed*.progress.csv")):
        seed = path.name[len(f"{scenario}-seed"):-len(".progress.csv")]   # not SCENARIO-seedK.stageJ.progress.csv
        if seed.isdigit():
            out[int(seed)] = read_progress(path)
    return out
