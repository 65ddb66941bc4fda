"""Test-wide settings: headless plotting, two threads, the course's fast mode."""
import os

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("MASP_LITE_FAST", "1")  # notebooks run with small budgets under test
os.environ.setdefault("OMP_NUM_THREADS", "1")

import torch  # noqa: E402

torch.set_num_threads(1)
