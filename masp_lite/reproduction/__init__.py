"""The reproduction room: the only code that knows the source checkout's layout.

Everything else in :mod:`masp_lite` works from an installed copy; this package holds what
needs the repository — its evaluation records under ``results/``, the kept training
histories and seeds under ``results/training/``, and the source tree's weights folder:

* :mod:`.paper` — the paper's numbers (its tables, by method, scenario and metric);
* :mod:`.reproduce` — the paper's tables from our records, ours beside the paper's
  (``python -m masp_lite reproduce``), and re-evaluating every record;
* :mod:`.claims` — the paper's comparisons, judged from records with their spreads;
* :mod:`.plan` — ``reproduce --train``: every kept training run, retrained from random networks;
* :mod:`.shipping` — keeping a finished run: its weights shipped, its history under ``results/training/``;
* :mod:`.histories` — reading the kept histories back (the shipped weights' stages, a recipe's seeds).
"""
from pathlib import Path

__all__ = ["REPO_ROOT", "RESULTS_DIR", "KEPT_DIR"]

#: The source checkout this package runs from (``masp_lite/reproduction/`` -> two levels up).
REPO_ROOT = Path(__file__).resolve().parents[2]
#: ``results/`` of the checkout: the committed evaluation records.
RESULTS_DIR = REPO_ROOT / "results"
#: ``results/training/``: training histories and the kept weights of training seeds and recipes.
KEPT_DIR = RESULTS_DIR / "training"
