"""Training curves: read a run's ``progress.csv`` and plot it.

A training run (:func:`masp_lite.training.train`) writes one ``progress.csv`` row per
iteration: environment steps, wall-clock, the training episodes' SR / Steps / CR (sampled
actions), both levels' mean rewards, losses and entropies, — every ``eval_every``
iterations — the deterministic evaluation (``eval_sr``, ``eval_steps``, ``eval_cr``; empty
cells in the other rows), and PPO's health per level (``gm_approx_kl``, ``gm_clip_fraction``,
``gm_explained_variance``, the same with ``cae_``: :data:`~masp_lite.algos.mappo.UPDATE_STATS`;
files written before 2026-12 have none of these columns). These functions are what chapters
05, 06 and 10 use to look at runs:

* :func:`read_progress` — the file as columns of floats (NaN where a cell is empty);
* :func:`last_evaluation` — the last row that has an evaluation;
* :func:`plot_progress` — SR, Steps, CR and both rewards against environment steps;
* :func:`plot_history` — every stage of a kept training history, end to end (chapter 06);
* :func:`plot_seed_bands` — the mean and band over seeds of several runs' curves (chapter 10's
  ablation figure).
* :func:`plot_ppo_health` — both levels' approximate KL, clip fraction and explained variance
  against environment steps (chapter 05);
* :class:`ProgressLine` — a training run's progress in a notebook as one line that updates
  in place (``train(..., progress=False, on_iteration=ProgressLine(updates))``): the saved
  notebook keeps that one line, where a text progress bar saves every redraw; it ends with
  PPO's health of the last iteration (:func:`health_text`).

Why columns of floats: a curve is plotted and compared as an array, and NaN keeps the
evaluation columns aligned with the iterations (``np.isnan`` finds the evaluated rows).

The kept histories of a source checkout (the shipped weights' stages, the ablations' seeds)
are read by the reproduction room (:mod:`masp_lite.reproduction.histories`).
"""
from __future__ import annotations

import csv
import io
import sys
import time
from pathlib import Path

import numpy as np

from ..algos.mappo import HEALTH
from ..files import read_bounded

__all__ = ["read_progress", "last_evaluation", "plot_progress", "plot_history", "plot_seed_bands", "plot_ppo_health",
           "health_text", "ProgressLine", "LEVELS", "HEALTH_NAMES"]

#: The two levels PPO trains, by their column prefix in ``progress.csv``.
LEVELS = {"gm": "Goal Matcher", "cae": "executor"}
#: PPO's health per level (``progress.csv``: ``gm_approx_kl``, ...; :data:`~masp_lite.algos.mappo.HEALTH`) in words.
HEALTH_NAMES = dict(zip(HEALTH, ("approximate KL", "clip fraction", "explained variance")))


def health_text(row: dict | None) -> str:
    """PPO's health in one line: ``"PPO KL 0.0040/0.0120, clipped 2%/9%, EV 0.31/0.78 (Goal Matcher/executor)"``.

    ``row``: an iteration's row (``MASPTrainer.iteration()``'s, or ``progress.csv``'s). A level that was not
    trained (NaN), or a row without these columns (an older run), shows ``-``; no row at all is ``""``."""
    if not row:
        return ""

    def both(key: str, fmt: str) -> str:
        values = [row.get(f"{level}_{key}") for level in LEVELS]
        return "/".join(format(float(v), fmt) if v not in (None, "") and float(v) == float(v) else "-"
                        for v in values)
    return (f"PPO KL {both('approx_kl', '.4f')}, clipped {both('clip_fraction', '.0%')}, "
            f"EV {both('explained_variance', '.2f')} ({'/'.join(LEVELS.values())})")


class ProgressLine:
    """``on_iteration`` for :func:`masp_lite.training.train`: one progress line, updated in place.

    In a notebook the line is a display that each iteration replaces, so the saved output is
    that single line; elsewhere it is rewritten with a carriage return. ``every`` limits how
    often it redraws.

    >>> line = ProgressLine(150, "MASP on mpe-5")   # doctest: +SKIP
    >>> train("mpe-5", cfg, out, progress=False, on_iteration=line)   # doctest: +SKIP
    """

    def __init__(self, total: int, label: str = "training", every: float = 1.0):
        if not isinstance(total, int) or isinstance(total, bool) or total < 1:
            raise ValueError(f"ProgressLine: total: expected a positive number of iterations, got {total!r}")
        self.total, self.label, self.every = total, label, float(every)
        self.start = self.shown = None
        self.handle = None
        self.first = None

    def text(self, iterations: int, env_steps: int | None = None) -> str:
        """The line for ``iterations`` done (elapsed time and an estimate of what is left)."""
        now = time.monotonic()
        if self.start is None:
            self.start, self.first = now, iterations - 1
        elapsed = now - self.start
        done = max(iterations - self.first, 1)
        left = elapsed / done * max(self.total - iterations, 0)
        steps = f", {env_steps:,} environment steps" if env_steps is not None else ""
        return (f"{self.label}: iteration {iterations}/{self.total}{steps}, {elapsed:.0f} s"
                + (f", about {left:.0f} s left" if iterations < self.total else ", done"))

    def __call__(self, trainer) -> None:
        iterations = int(trainer.iterations)
        line = self.text(iterations, getattr(trainer, "env_steps", None))
        health = health_text(getattr(trainer, "last_row", None))
        line += f" | {health}" if health else ""
        now = time.monotonic()
        if self.shown is not None and now - self.shown < self.every and iterations < self.total:
            return
        self.shown = now
        try:
            from IPython import get_ipython
            from IPython.display import display
            in_kernel = get_ipython() is not None and "IPKernelApp" in get_ipython().config
        except ImportError:  # pragma: no cover - IPython ships with the course requirements
            in_kernel = False
        if in_kernel:
            if self.handle is None:
                self.handle = display(_Line(line), display_id=True)
            else:
                self.handle.update(_Line(line))
        else:
            end = "\n" if iterations >= self.total else ""
            print("\r" + line, end=end, file=sys.stderr, flush=True)


class _Line:
    """A line of text for IPython's display (plain text; no markup)."""

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        return self.text



def read_progress(path) -> dict[str, np.ndarray]:
    """``progress.csv`` at ``path`` as ``{column: float array}``, one entry per iteration.

    Empty cells (the evaluation columns between evaluations) are NaN. A missing file, a
    file without a header or rows, or a cell that is not a number is one ``ValueError``.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"read_progress: expected an existing progress.csv, got {str(path)!r}")
    reader = csv.DictReader(io.StringIO(read_bounded(path, what="progress.csv").decode("utf-8", "replace"),
                                        newline=""))
    rows = list(reader)
    fields = reader.fieldnames or []
    if not fields or not rows:
        raise ValueError(f"read_progress: {path.name} has no rows (expected a header and one row per iteration)")
    columns = {}
    for key in fields:
        try:
            columns[key] = np.array([float(r[key]) if r[key] not in ("", None) else np.nan for r in rows])
        except ValueError:
            raise ValueError(f"read_progress: {path.name}, column {key!r}: expected numbers") from None
    return columns


def last_evaluation(columns: dict) -> dict | None:
    """``{"iteration", "env_steps", "sr", "steps", "cr"}`` of the last evaluated row, or ``None``."""
    done = np.flatnonzero(~np.isnan(columns["eval_sr"]))
    if not len(done):
        return None
    i = done[-1]
    return {"iteration": int(columns["iteration"][i]), "env_steps": int(columns["env_steps"][i]),
            **{k: float(columns[f"eval_{k}"][i]) for k in ("sr", "steps", "cr")}}


def _recorded(values) -> bool:
    """Whether a progress column holds any number (a column of NaN draws no line, so it gets no key either)."""
    return bool(np.isfinite(np.asarray(values, dtype=float)).any())


def plot_progress(columns: dict, title: str = "", baseline: dict | None = None, baseline_label: str = "h-greedy"):
    """One figure of training curves against environment steps; returns the figure.

    Three panels (SR ↑, Steps ↓, CR ↓) show the training rollouts (sampled actions) and the
    periodic evaluation (deterministic policies), in the words of ``train``'s progress bar;
    ``baseline`` (``{"sr", "steps", "cr"}`` means, e.g. h-greedy's) adds a dashed line,
    labelled ``baseline_label``, to each. A fourth panel shows the mean rewards of both
    levels, R_GM (eq. 1) and R_CAE (eq. 5). Call ``plt.show()`` (or let the notebook show it).
    A column without a number (NaN throughout: R_GM of a run whose Goal Matcher is not trained)
    draws no line and has no key entry; the rewards panel's key says which reward was not recorded.
    The three metric panels share one key, under them, so that it never hides a curve.
    The step axes carry at most five ticks in thousands / millions (``50k``, ``1.2M``), so
    their labels never run into each other on the narrow panels.
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import EngFormatter, MaxNLocator

    x = columns["env_steps"]
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.2))
    for ax, (key, label) in zip(axes, [("sr", "SR ↑"), ("steps", "Steps ↓"), ("cr", "CR ↓")]):
        if _recorded(columns[f"train_{key}"]):
            ax.plot(x, columns[f"train_{key}"], color="C0", alpha=0.5, label="training rollouts (sampled)")
        evaluated = ~np.isnan(columns[f"eval_{key}"])
        if evaluated.any():
            ax.plot(x[evaluated], columns[f"eval_{key}"][evaluated], "o-", color="C1",
                    label="evaluation (deterministic)")
        if baseline is not None and baseline.get(key) is not None:
            ax.axhline(baseline[key], color="k", ls="--", lw=1, label=baseline_label)
        ax.set(title=label, xlabel="environment steps")
    # one key for the three metric panels, under them: inside a panel it covered the evaluation
    # points and the baseline (an SR curve near 1 fills the top of its panel, the bottom of Steps')
    handles, labels = [], []
    for ax in axes[:3]:
        for handle, text in zip(*ax.get_legend_handles_labels()):
            if text not in labels:
                handles.append(handle)
                labels.append(text)
    # a level that is not trained (the Goal Matcher under Hungarian goals) has no reward: NaN throughout,
    # so it gets no line, and no entry in the key, only a note
    rewards, unrecorded = axes[3], []
    for key, label, color in (("gm_reward", "R_GM (eq. 1)", "C0"), ("cae_reward", "R_CAE (eq. 5)", "C1")):
        if _recorded(columns[key]):
            rewards.plot(x, columns[key], color=color, label=label)
        else:
            unrecorded.append(label.split()[0])
    rewards.set(title="mean rewards", xlabel="environment steps")
    note = f"no {' or '.join(unrecorded)} recorded" if unrecorded else None
    if rewards.get_lines():  # the note heads the key, which matplotlib places away from the curves
        rewards.legend(fontsize=8, title=note, title_fontsize=7)
    else:
        rewards.text(0.5, 0.5, note, transform=rewards.transAxes, ha="center", fontsize=8, color="0.4")
    for ax in axes:
        ax.xaxis.set_major_locator(MaxNLocator(nbins=4, integer=True))
        ax.xaxis.set_major_formatter(EngFormatter(sep=""))
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.09, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False,
               bbox_to_anchor=(0.38, 0.0))
    return fig


def plot_history(history: dict, title: str = "", names=None):
    """Every stage of a training history in one figure, end to end along environment steps; returns it.

    ``history``: a kept history (:func:`masp_lite.reproduction.histories.training_history`:
    ``{"stages": [{"progress": path or None, "training": {...}}, ...]}``, oldest stage first).
    Three panels (SR ↑, Steps ↓, CR ↓) draw each stage's training rollouts and evaluations,
    its environment steps counted on from where the stage before ended; a dotted line and the
    stage's number above the panel (or its name from ``names``) mark where each stage starts. A stage whose
    curve is not kept leaves a gap as long as its recorded environment steps. The periodic
    evaluations of a stage run on that stage's own scenario and settings, so compare points
    within a stage rather than across them.
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import EngFormatter, MaxNLocator

    stages = history.get("stages", [])
    fig, axes = plt.subplots(1, 3, figsize=(15, 3.4))
    offset = 0.0
    for k, stage in enumerate(stages):
        label = names[k] if names is not None and k < len(names) else str(k + 1)
        info = stage.get("training") or {}
        columns = read_progress(stage["progress"]) if stage.get("progress") else None
        for ax in axes:
            ax.axvline(offset, color="0.6", ls=":", lw=1)
            ax.annotate(label, (offset, 1.0), xycoords=("data", "axes fraction"), xytext=(2, 2),
                        textcoords="offset points", fontsize=7, color="0.3")
        if columns is None or len(columns["env_steps"]) == 0:
            offset += float(info.get("env_steps") or 0)
            continue
        x = offset + columns["env_steps"]
        for ax, key in zip(axes, ("sr", "steps", "cr")):
            ax.plot(x, columns[f"train_{key}"], color="C0", alpha=0.4, lw=1,
                    label="training rollouts (sampled)" if k == 0 else None)
            done = ~np.isnan(columns[f"eval_{key}"])
            ax.plot(x[done], columns[f"eval_{key}"][done], "o-", color="C1", ms=3, lw=1,
                    label="evaluation (deterministic)" if k == 0 else None)
        offset = float(x[-1])
    for ax, label in zip(axes, ("SR ↑", "Steps ↓", "CR ↓")):
        ax.set_title(label, pad=12)
        ax.set(xlabel="environment steps, stage after stage", ylabel=label.split()[0])
        ax.xaxis.set_major_locator(MaxNLocator(nbins=4, integer=True))
        ax.xaxis.set_major_formatter(EngFormatter(sep=""))
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    return fig


def plot_seed_bands(groups: dict, key: str = "train_sr", smooth: int = 5, ax=None, ylabel: str | None = None):
    """Mean and min–max band over seeds of column ``key`` against environment steps, one line per group.

    ``groups``: ``{label: {seed: columns}}`` (e.g. :func:`~masp_lite.reproduction.histories.kept_curves`
    of each variant). Each seed's
    curve is smoothed by a running mean over ``smooth`` iterations and cut to the shortest
    seed of its group; a group with one seed is a line without a band. Returns the axes."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import EngFormatter, MaxNLocator

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 3.6))
    kernel = np.ones(max(1, smooth)) / max(1, smooth)
    for label, seeds in groups.items():
        if not seeds:
            continue
        n = min(len(c[key]) for c in seeds.values())
        ys = np.stack([np.convolve(c[key][:n], kernel, mode="valid") for c in seeds.values()])
        x = next(iter(seeds.values()))["env_steps"][:n][len(kernel) - 1:]
        line, = ax.plot(x, ys.mean(0), label=f"{label} ({len(seeds)} seed{'s' if len(seeds) > 1 else ''})")
        if len(seeds) > 1:
            ax.fill_between(x, ys.min(0), ys.max(0), color=line.get_color(), alpha=0.2)
    ax.set(xlabel="environment steps", ylabel=ylabel or key)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=5, integer=True))
    ax.xaxis.set_major_formatter(EngFormatter(sep=""))
    ax.legend(fontsize=8)
    return ax


def plot_ppo_health(columns: dict, title: str = "", smooth: int = 1):
    """Both levels' PPO health against environment steps, one panel per statistic; returns the figure.

    Approximate KL (how far each update moved the policy from the one that collected the rollout),
    clip fraction (the share of samples whose probability ratio the clip stopped) and explained
    variance of the critic (1: it predicts the returns; 0: no better than their mean). ``columns``:
    :func:`read_progress` of a run; ``smooth``: a running mean over that many iterations. A run
    written before these columns existed is one clear error."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import EngFormatter, MaxNLocator

    missing = [f"{level}_{k}" for level in LEVELS for k in HEALTH_NAMES if f"{level}_{k}" not in columns]
    if missing:
        raise ValueError(f"plot_ppo_health: the run has no columns {missing} (written before PPO's health was "
                         "logged, 2026-12); expected the progress.csv of a newer run")
    kernel = np.ones(max(1, smooth)) / max(1, smooth)
    x = columns["env_steps"][len(kernel) - 1:]
    fig, axes = plt.subplots(1, len(HEALTH_NAMES), figsize=(13, 3.2))
    for ax, (key, label) in zip(axes, HEALTH_NAMES.items()):
        for level, name in LEVELS.items():
            y = columns[f"{level}_{key}"]
            if not np.isnan(y).all():  # a level that was not trained (frozen, or scripted goals) has none
                ax.plot(x, np.convolve(y, kernel, mode="valid"), label=name)
        ax.set(title=label, xlabel="environment steps")
        ax.xaxis.set_major_locator(MaxNLocator(nbins=4, integer=True))
        ax.xaxis.set_major_formatter(EngFormatter(sep=""))
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return fig
