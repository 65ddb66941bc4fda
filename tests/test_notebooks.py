"""Every chapter runs top to bottom under nbval, both versions, in fast mode.

Each notebook runs in its own ``pytest --nbval-lax`` subprocess (a fresh kernel from this
environment, ``MASP_LITE_FAST=1``), so the default ``python -m pytest`` covers the course
without collecting notebooks itself. Instructor versions must pass every graded check;
learner versions run as shipped (their graded cells carry the ``raises-exception`` tag).

nbval stops each kernel by killing it, so a chapter's ``tempfile.TemporaryDirectory`` (chapter
06's ``masp-run-*`` run folder) is never removed by the kernel. Each test gives its subprocess a
temporary folder of its own (``TMPDIR``, inside pytest's ``tmp_path``, which pytest rotates), and
checks that chapter 06's run folder landed there. The test never looks at the system's shared
temporary folder: another process running chapter 06 or 11 at the same moment makes its own
``masp-run-*`` folders there, and they are none of this test's business.
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
#: Chapters whose run folder outlives their kernel (a ``TemporaryDirectory`` kept for the whole chapter).
KEEPS_A_RUN_FOLDER = {"06_training_masp"}


@pytest.mark.notebook
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[f"{p.parent.name}/{p.stem}" for p in NOTEBOOKS])
def test_notebook_runs_under_nbval(path, tmp_path):
    own_tmp = tmp_path / "tmp"  # this test's own: nothing another process does can appear here
    own_tmp.mkdir()
    env = dict(os.environ, MASP_LITE_FAST="1", MPLBACKEND="Agg", PYDEVD_DISABLE_FILE_VALIDATION="1",
               TMPDIR=str(own_tmp))
    cmd = [sys.executable, "-m", "pytest", "--nbval-lax", "--nbval-current-env", "-q", "-p", "no:cacheprovider",
           "-p", "no:randomly", "--nbval-cell-timeout", str(LIMIT_S), str(path.relative_to(ROOT))]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=LIMIT_S)
    took = time.perf_counter() - start
    assert proc.returncode == 0, f"{path.name} failed under nbval:\n{proc.stdout[-6000:]}\n{proc.stderr[-2000:]}"
    if path.stem in KEEPS_A_RUN_FOLDER:  # the kernel used this test's temp folder, not the system's
        assert list(own_tmp.glob("masp-run-*")), f"{path.name} made no run folder in its own temp folder {own_tmp}"
    print(f"{path.parent.name}/{path.name}: {took:.0f} s")
