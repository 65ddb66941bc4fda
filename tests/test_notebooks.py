"""Every chapter runs top to bottom under nbval, both versions, in fast mode.

Each notebook runs in its own ``pytest --nbval-lax`` subprocess (a fresh kernel from this
environment, ``MASP_LITE_FAST=1``), so the default ``python -m pytest`` covers the course
without collecting notebooks itself. Instructor versions must pass every graded check;
learner versions run as shipped (their graded cells carry the ``raises-exception`` tag).

nbval stops each kernel by killing it, so a chapter's ``tempfile.TemporaryDirectory`` (chapter
06's ``masp-run-*`` run folder) is never removed by the kernel: the subprocess gets pytest's own
``tmp_path`` as its temp dir (``TMPDIR``), which pytest rotates, and the test checks that no new
``masp-run-*`` folder appears in the system temp dir.
"""
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "solutions").glob("*.ipynb")) + sorted((ROOT / "notebooks").glob("*.ipynb"))
LIMIT_S = 600  # hard stop; a chapter should take about a minute (3 minutes at most) on 2 cores


def _run_folders() -> set[Path]:
    return set(Path(tempfile.gettempdir()).glob("masp-run-*"))


@pytest.mark.notebook
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[f"{p.parent.name}/{p.stem}" for p in NOTEBOOKS])
def test_notebook_runs_under_nbval(path, tmp_path):
    env = dict(os.environ, MASP_LITE_FAST="1", MPLBACKEND="Agg", PYDEVD_DISABLE_FILE_VALIDATION="1",
               TMPDIR=str(tmp_path))
    before = _run_folders()
    cmd = [sys.executable, "-m", "pytest", "--nbval-lax", "--nbval-current-env", "-q", "-p", "no:cacheprovider",
           "-p", "no:randomly", "--nbval-cell-timeout", str(LIMIT_S), str(path.relative_to(ROOT))]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=LIMIT_S)
    took = time.perf_counter() - start
    assert proc.returncode == 0, f"{path.name} failed under nbval:\n{proc.stdout[-6000:]}\n{proc.stderr[-2000:]}"
    left = sorted(map(str, _run_folders() - before))
    assert left == [], f"{path.name} left run folders in the system temp dir: {left}"
    print(f"{path.parent.name}/{path.name}: {took:.0f} s")
