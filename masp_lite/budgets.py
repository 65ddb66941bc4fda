"""One stage of a recipe at a budget of your own: what a laptop can afford of a long training run.

A recipe (:mod:`masp_lite.recipes`) fixes each stage's world, settings, starting point and
budget (iterations x worlds), and ``train --recipe`` refuses to change the budget, so that a
kept history is a record of the recipe itself. To learn what a stage does, a smaller run of
the same stage is enough: the same scenario, the same settings and world overrides, the same
kind of starting weights, fewer iterations over fewer worlds. :func:`train_stage_at` trains
it (chapter 06 has the learner write it).

Example: the ``mpe-5`` stage of the shipped MASP, 20 iterations of 16 worlds, from the
shipped ``mpe-20`` weights it fine-tunes::

    from masp_lite.budgets import train_stage_at
    from masp_lite.weights import HERE
    manifest = train_stage_at("masp", "mpe-5", seed=0, out="runs/my-mpe-5", iterations=20,
                              worlds=16, init=HERE / "mpe-20.pt")
"""
from __future__ import annotations

from .config import TrainConfig
from .recipes import get_recipe, stage_config
from .training import train

__all__ = ["stage_at", "train_stage_at"]


def stage_at(recipe: str, stage: str, iterations: int, worlds: int, evaluations: int = 2):
    """``(scenario, method, TrainConfig, scenario overrides)`` of ``recipe``'s ``stage`` with a new budget.

    Everything the stage trains with stays; only the budget changes, and with it how often the
    run evaluates and saves: ``evaluations`` times in all (at least once, at the end)."""
    if iterations < 1 or worlds < 1 or evaluations < 1:
        raise ValueError(f"stage_at: expected iterations, worlds and evaluations >= 1, got "
                         f"{iterations}, {worlds}, {evaluations}")
    chosen = get_recipe(recipe).stage(stage)
    method, cfg, overrides = stage_config(get_recipe(recipe), chosen)
    every = max(1, iterations // evaluations)
    flat = {**cfg.flat(), "updates": iterations, "num_envs": worlds, "eval_every": every, "checkpoint_every": every}
    return chosen.scenario, method, TrainConfig.from_flat(flat), overrides


def train_stage_at(recipe: str, stage: str, seed: int, out, iterations: int, worlds: int, init=None,
                   evaluations: int = 2, on_iteration=None) -> dict:
    """Train ``recipe``'s ``stage`` for ``iterations`` x ``worlds`` in the run folder ``out``; returns its manifest.

    ``init``: the weights to start from (the stage's own ``start`` is a stage of a recipe run,
    e.g. the shipped weights of that stage); ``None`` starts from random networks."""
    scenario, method, cfg, overrides = stage_at(recipe, stage, iterations, worlds, evaluations)
    return train(scenario, cfg, out, seed=seed, init=init, overrides=overrides, method=method,
                 progress=False, on_iteration=on_iteration)
