"""Research scripts on masp-lite's public API; each asks one question (see ``experiments/README.md``)."""
from __future__ import annotations

import csv
from pathlib import Path


def print_validation(out, label: str = "validation SR") -> None:
    """Print the periodic validation rows of a training run's ``progress.csv`` in ``out``."""
    with open(Path(out) / "progress.csv") as f:
        for row in csv.DictReader(f):
            if row["eval_sr"]:
                sr, st, cr = (float(row[f"eval_{k}"]) for k in ("sr", "steps", "cr"))
                print(f"iteration {row['iteration']:>3}  wall {float(row['wall_s']):6.0f} s  {label} {sr:.3f}  "
                      f"Steps {st:6.1f}  CR {cr:.4f}")
