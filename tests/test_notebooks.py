"""Every chapter runs top to bottom under nbval, both versions, in fast mode.

Each notebook runs in its own ``pytest --nbval-lax`` subprocess (a fresh kernel from this
environment, ``MASP_LITE_FAST=1``), so the default ``python -m pytest`` covers the course
without collecting notebooks itself. Instructor versions must pass every graded check;
learner versions run as shipped (their graded cells carry the ``raises-exception`` tag).
"""
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "solutions").glob("*.ipynb")) + sorted((ROOT / "notebooks").glob("*.ipynb"))
LIMIT_S = 600  # hard stop; a chapter should take about a minute (3 minutes at most) on 2 cores


@pytest.mark.notebook
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[f"{p.parent.name}/{p.stem}" for p in NOTEBOOKS])
def test_notebook_runs_under_nbval(path):
    env = dict(os.environ, MASP_LITE_FAST="1", MPLBACKEND="Agg", PYDEVD_DISABLE_FILE_VALIDATION="1")
    cmd = [sys.executable, "-m", "pytest", "--nbval-lax", "--nbval-current-env", "-q", "-p", "no:cacheprovider",
           "-p", "no:randomly", "--nbval-cell-timeout", str(LIMIT_S), str(path.relative_to(ROOT))]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=LIMIT_S)
    took = time.perf_counter() - start
    assert proc.returncode == 0, f"{path.name} failed under nbval:\n{proc.stdout[-6000:]}\n{proc.stderr[-2000:]}"
    print(f"{path.parent.name}/{path.name}: {took:.0f} s")
