"""Test-wide settings: headless plotting, one torch thread that waits passively, the course's fast mode."""
import os

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("MASP_LITE_FAST", "1")  # notebooks run with small budgets under test
os.environ.setdefault("OMP_NUM_THREADS", "1")

# masp_lite before torch: it sets OMP_WAIT_POLICY=PASSIVE, so torch's threads (here, and in the notebooks'
# kernels and the CLI subprocesses that inherit this environment) sleep instead of spinning while they
# wait, as the product's do (masp_lite.threads)
# isort: off
import masp_lite  # noqa: E402, F401
import torch  # noqa: E402
# isort: on

torch.set_num_threads(1)
