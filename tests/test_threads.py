"""Torch's threads wait passively wherever the product starts, and the course says when they cannot.

Each case runs a fresh interpreter: OpenMP reads ``OMP_WAIT_POLICY`` once, when torch is first imported,
so only the order of imports in a new process shows what the product does. (How much passive waiting buys
is ``bench busy``'s to measure, never a timed test's.)
"""
import json
import os
import subprocess
import sys
import warnings

import pytest

import masp_lite
from masp_lite import course
from masp_lite.threads import EVALUATE_THREADS, TRAIN_THREADS, passive_wait

REPORT = ("import json, os, sys\nfrom masp_lite.threads import passive_wait\n"
          "print(json.dumps([os.environ.get('OMP_WAIT_POLICY'), passive_wait(), 'torch' in sys.modules]))")


def _fresh(code: str, **env) -> list:
    """Run ``code`` in a new interpreter whose environment has no OMP_WAIT_POLICY unless ``env`` gives one."""
    base = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    out = subprocess.run([sys.executable, "-c", code + "\n" + REPORT], env={**base, **env},
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


@pytest.mark.parametrize("first", ["import masp_lite", "import masp_lite.course", "from masp_lite.cli import main"])
def test_importing_the_package_before_torch_makes_torch_wait_passively(first):
    assert _fresh(f"{first}\nimport torch") == ["PASSIVE", True, True]


def test_a_users_own_policy_wins():
    assert _fresh("import masp_lite\nimport torch", OMP_WAIT_POLICY="ACTIVE") == ["ACTIVE", False, True]
    assert _fresh("import masp_lite\nimport torch", OMP_WAIT_POLICY="passive") == ["passive", True, True]


def test_torch_imported_first_is_reported_not_hidden():
    """Too late to choose: the package sets nothing and says the threads may spin."""
    assert _fresh("import torch\nimport masp_lite") == [None, False, True]


def test_the_command_line_sets_it_before_torch(tmp_path):
    """``python -m masp_lite`` (what the README runs): the CLI process itself waits passively."""
    probe = tmp_path / "sitecustomize.py"  # runs at the CLI's exit, after the command imported torch
    probe.write_text("import atexit, os, sys\n"
                     "atexit.register(lambda: print('POLICY', os.environ.get('OMP_WAIT_POLICY'), "
                     "'torch' in sys.modules))\n")
    base = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    env = {**base, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    out = subprocess.run([sys.executable, "-m", "masp_lite", "evaluate", "--method", "h-greedy", "--scenario",
                          "mpe-5", "--episodes", "1", "--seeds", "0"], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "POLICY PASSIVE True"


def test_this_test_process_waits_passively():
    """The root conftest imports masp_lite before torch, as the product does."""
    assert passive_wait() and os.environ["OMP_WAIT_POLICY"] == "PASSIVE"


def test_setup_warns_when_two_threads_would_spin(monkeypatch):
    import torch
    before = torch.get_num_threads()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no warning while the threads wait passively
            course.setup(seed=0)
            assert torch.get_num_threads() == TRAIN_THREADS
        monkeypatch.setattr(masp_lite, "_torch_wait_policy", None)  # as if torch had been imported first
        with pytest.warns(RuntimeWarning, match="import masp_lite before torch, or call setup\\(threads=1\\)"):
            course.setup(seed=0, threads=2)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            course.setup(seed=0, threads=1)  # one thread has no one to wait for
    finally:
        torch.set_num_threads(before)


def test_the_thread_counts_are_the_documented_ones():
    from masp_lite.bench import busy, decide, env, train
    from masp_lite.cli import evaluate as cli_evaluate
    from masp_lite.cli import train as cli_train

    def default(module, flag="--threads"):
        import argparse
        parser = argparse.ArgumentParser()
        module.add_arguments(parser)
        return next(a.default for a in parser._actions if flag in a.option_strings)

    assert EVALUATE_THREADS == 1 and TRAIN_THREADS == 1
    assert default(cli_evaluate) == default(env) == default(decide) == EVALUATE_THREADS
    assert default(cli_train) == default(train) == TRAIN_THREADS
    assert busy.LOOPS["world"][1] == busy.LOOPS["decide"][1] == EVALUATE_THREADS
    assert busy.LOOPS["train"][1] == TRAIN_THREADS
