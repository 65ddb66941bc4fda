"""A playground: two methods side by side on the same layout, with SR / Steps / CR ticking.

Pick a scenario, a team size, a seed and two methods; both methods run one episode from the
*same* reset (same scenario, same seed, so the same agents, landmarks and obstacles — checked
by :func:`same_layout`), and a step slider walks through them together:

* particle scenarios (``mpe-*``): the two 2-D views of :mod:`.anim2d` (its :class:`~.anim2d.Scene`,
  goal lines and short trails) at the slider's step;
* drone scenarios: the two standalone meshcat pages of :mod:`.meshcat3d`, which play their
  own 3-D animation (meshcat's "Animations" panel), each with its key under it; the slider
  moves the metrics only, and says so beside it (:data:`SLIDER_NOTE_3D`).

Under the views, one line per method gives SR, Steps and CR *so far*: :func:`metrics_at` runs
the course's own functions (:mod:`masp_lite.evaluation.metrics`) on the episode cut after
``t`` steps, so at the last step the numbers are the episode's metrics as ``evaluate``
computes them, and before it they are what they would be had the episode ended there
(Steps shows "—" until SR has reached 1).

Three entry points, from pure to interactive:

* :func:`rollout_pair` — the two :class:`Episode` objects (frames or 3-D recording, and the
  :class:`~masp_lite.evaluation.metrics.EpisodeLog` the metrics read), no widgets;
* :class:`Playground` — the ipywidgets (``scenario``, ``team_size``, ``seed``, ``method_a``,
  ``method_b``, ``run_button``, ``step``), usable from Python: set values, ``run_button.click()``;
* :func:`show` — a :class:`Playground` in a live notebook; elsewhere (plain Python, a terminal,
  a notebook run headless by nbval, whose kernel inherits pytest's ``PYTEST_CURRENT_TEST``)
  the :func:`static` page: the two animations side by side, with the whole-episode metrics.

ipywidgets, matplotlib and meshcat are imported on first use, so importing this module needs
none of them. Learned methods load their shipped weights; the defaults (``h-greedy`` against
``masp`` on ``mpe-5``) run in a few seconds on a CPU.
"""
from __future__ import annotations

import base64
import html
import io
import os
import time
from dataclasses import dataclass

import numpy as np
import torch

from ..envs import SCENARIOS, Scenario, get_scenario, make, scenario_names
from ..evaluation.metrics import EpisodeLog, collision_rate, reached_target, steps, success_rate
from ..evaluation.rollouts import rollout
from ..policies import build_policy, get_factory, method_names
from ..policies import method_options as options_of

__all__ = ["Episode", "Playground", "rollout_pair", "metrics_at", "team_sizes", "same_layout", "static", "show",
           "TRAIL", "SLIDER_NOTE_3D"]

#: Earlier frames each agent's trail spans in the 2-D views.
TRAIL = 6


@dataclass
class Episode:
    """One method's episode in the playground (world 0 of a one-world batch)."""

    method: str
    """Registered method name (:data:`masp_lite.policies.METHODS`)."""
    scenario: Scenario
    """The scenario played, team-size override included."""
    seed: int
    """Seed of the world's reset and of the method (when it takes one)."""
    log: EpisodeLog
    """What the metrics read: covered / reached / alive per step, collisions per step."""
    frames: list[dict] | None = None
    """Particle scenarios: the ``horizon + 1`` frames of :func:`masp_lite.viz.anim2d.record`."""
    recording: dict | None = None
    """Drone scenarios: the arrays of :func:`masp_lite.viz.meshcat3d.record_episode`."""

    @property
    def horizon(self) -> int:
        return self.log.horizon


def team_sizes(scenario, overrides=None) -> list[int]:
    """Team sizes to offer for ``scenario``: the presets' sizes of its kind that keep it valid.

    A size is kept when ``get_scenario(scenario, num_agents=n, **overrides)`` accepts it (the
    map still holds every body; a team change still shrinks the team). The scenario's own
    size is always offered.

    >>> team_sizes("mpe-5"), team_sizes("mpe-20to10")
    ([5], [20, 50])
    """
    rest = {k: v for k, v in dict(overrides or {}).items() if k != "num_agents"}
    base = get_scenario(scenario, **dict(overrides or {}))
    sizes = sorted({s.num_agents for s in SCENARIOS.values() if s.kind == base.kind} | {base.num_agents})
    ok = []
    for n in sizes:
        try:
            get_scenario(scenario, **rest, num_agents=n)
        except ValueError:
            continue
        ok.append(n)
    return ok


def _check(method_a, method_b, seed) -> None:
    for m in (method_a, method_b):
        if not isinstance(m, str):
            raise ValueError(f"method: expected a name, one of {method_names()}, got {m!r}")
        get_factory(m)  # an unknown name fails here, with the list of valid ones
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected a non-negative int, got {seed!r}")


def _scenario(scenario, team_size, overrides) -> Scenario:
    overrides = dict(overrides or {})
    if team_size is not None:
        if overrides.get("num_agents", team_size) != team_size:
            raise ValueError(f"team_size={team_size!r} and overrides num_agents={overrides['num_agents']!r}: "
                             "expected one team size")
        overrides["num_agents"] = team_size
    return get_scenario(scenario, **overrides)


def _policy(method: str, world, seed: int):
    """The method's policy as ``play`` builds it: the seed reaches the method when it takes one."""
    factory = get_factory(method)
    options = {"seed": int(seed)} if "seed" in options_of(factory)[0] else {}
    return build_policy(factory, method, world, options)


def _log_from_frames(frames: list[dict], varying: bool, horizon: int) -> EpisodeLog:
    """The EpisodeLog of a recorded 2-D episode: frames carry covered/reached/alive and collisions so far."""
    stack = lambda key: torch.from_numpy(np.stack([f[key] for f in frames]).astype(bool))[None]  # noqa: E731
    so_far = np.array([f["collisions"] for f in frames], dtype=np.int64)
    return EpisodeLog(stack("covered"), stack("reached"), torch.from_numpy(np.diff(so_far))[None], stack("alive"),
                      varying=varying, horizon=horizon)


def _episode(method: str, sc: Scenario, seed: int) -> Episode:
    if sc.kind == "particle":
        from .anim2d import record

        world = make(sc, num_envs=1, seed=seed)
        frames = record(world, _policy(method, world, seed), seed=seed)
        return Episode(method, sc, int(seed), _log_from_frames(frames, sc.varying, int(world.horizon)), frames=frames)
    from .meshcat3d import record_episode

    def factory(world):
        return _policy(method, world, seed)

    factory.__name__ = method
    recording = record_episode(factory, sc, seed=seed)
    # The 3-D recording keeps every few steps and no contacts: the metrics come from a second,
    # identical run (same seed, same policy) through the rollout that evaluate uses.
    world = make(sc, num_envs=1, seed=seed)
    log, _ = rollout(world, factory(world), 1, seed=seed)
    if not np.array_equal(log.reached[0, -1].numpy(), recording["reached"][-1]):
        raise RuntimeError(f"{method} on {sc.name}: two runs with seed {seed} differ; expected a deterministic method")
    return Episode(method, sc, int(seed), log, recording=recording)


def same_layout(a: Episode, b: Episode) -> bool:
    """True when both episodes start from the same agents, landmarks and obstacles."""
    if a.frames is not None and b.frames is not None:
        return all(np.array_equal(a.frames[0][k], b.frames[0][k]) for k in ("agent_pos", "landmark_pos",
                                                                              "obstacle_pos"))
    if a.recording is not None and b.recording is not None:
        return np.array_equal(a.recording["landmark_pos"], b.recording["landmark_pos"]) and \
            np.array_equal(a.recording["pos"][0], b.recording["pos"][0])
    return False


def rollout_pair(scenario="mpe-5", team_size: int | None = None, seed: int = 0, method_a: str = "h-greedy",
                 method_b: str = "masp", overrides=None) -> tuple[Episode, Episode]:
    """One episode of each method on ``scenario`` with ``team_size`` agents, both reset with ``seed``.

    ``overrides`` are scenario overrides (as ``play --set``, e.g. ``{"horizon": 6}``);
    ``team_size`` ``None`` keeps the scenario's. A bad name or value fails with one ValueError
    before anything runs.
    """
    _check(method_a, method_b, seed)
    sc = _scenario(scenario, team_size, overrides)
    a, b = _episode(method_a, sc, seed), _episode(method_b, sc, seed)
    if not same_layout(a, b):
        raise RuntimeError(f"{method_a} and {method_b} on {sc.name} with seed {seed} started from different layouts")
    return a, b


def metrics_at(episode: Episode | EpisodeLog, t: int) -> dict:
    """SR / Steps / CR after ``t`` steps: the course's metrics on the episode cut after step ``t``.

    Returns ``{"t", "success_rate", "steps", "reached_target", "collision_rate"}``: SR is the
    coverage at ``t`` (varying teams: landmarks reached by ``t``); Steps is the first step with
    SR 1, or the horizon while ``reached_target`` is False; CR is the collisions so far per step
    (0 at ``t = 0``). At ``t = horizon`` these are :func:`~masp_lite.evaluation.metrics.success_rate`,
    :func:`~masp_lite.evaluation.metrics.steps` and :func:`~masp_lite.evaluation.metrics.collision_rate`
    of the whole episode (means over its episodes, if the log holds several).
    """
    log = episode.log if isinstance(episode, Episode) else episode
    last = log.collisions.shape[1]
    if isinstance(t, bool) or not isinstance(t, (int, np.integer)) or not 0 <= t <= last:
        raise ValueError(f"t: expected a step in [0, {last}], got {t!r}")
    t = int(t)
    cut = EpisodeLog(log.covered[:, :t + 1], log.reached[:, :t + 1], log.collisions[:, :t], log.alive[:, :t + 1],
                     varying=log.varying, horizon=log.horizon)
    return {"t": t, "success_rate": float(success_rate(cut).mean()), "steps": float(steps(cut).mean()),
            "reached_target": bool(reached_target(cut).any()),
            "collision_rate": float(collision_rate(cut).mean()) if t else 0.0}


def _table(episodes, t: int | None = None) -> str:
    """An HTML table of each episode's metrics at step ``t`` (default: the end)."""
    rows = []
    for ep in episodes:
        m = metrics_at(ep, ep.horizon if t is None else min(t, ep.horizon))
        steps_text = f"{m['steps']:.0f}" if m["reached_target"] else "—"
        rows.append(f"<tr><td><b>{html.escape(ep.method)}</b></td><td>{m['success_rate']:.2f}</td>"
                    f"<td>{steps_text}</td><td>{m['collision_rate']:.2f}</td></tr>")
    step = episodes[0].horizon if t is None else t
    return (f'<table style="font-family:sans-serif;font-size:13px"><tr><th>t = {step}/{episodes[0].horizon}</th>'
            "<th>SR</th><th>Steps</th><th>CR</th></tr>" + "".join(rows) + "</table>")


def _title(episodes) -> str:
    sc, seed = episodes[0].scenario, episodes[0].seed
    return f"{episodes[0].method} vs {episodes[1].method} on {sc.name}, {sc.num_agents} agents, seed {seed}"


def _iframes(episodes, height: int = 420) -> str:
    """The two meshcat pages side by side, each with its key under it (an overlay would cover a narrow pane)."""
    from .meshcat3d import episode_html, key_html, notebook_html

    cells = "".join(f'<div style="flex:1;min-width:320px">'
                    f"{notebook_html(episode_html(ep.recording, key=False), height).data}"
                    f"{key_html(ep.recording)}</div>" for ep in episodes)
    return f'<div style="display:flex;gap:8px">{cells}</div>'


#: What the step slider does with drone scenarios, said beside it.
SLIDER_NOTE_3D = ("the slider moves the metrics below; the 3-D views play by themselves "
                  "(Open Controls → Animations to pause or replay)")


def _error(e: Exception) -> str:
    return f'<span style="color:#b00">{html.escape(str(e))}</span>'


def static(episodes: tuple[Episode, Episode]):
    """The pair from :func:`rollout_pair` as one ``IPython.display.HTML`` page, no widgets needed.

    Particle scenarios: the two :func:`~.anim2d.animate` videos (:func:`~.anim2d.player`)
    side by side; drones: the two meshcat pages. The whole-episode metrics table follows.
    """
    from IPython.display import HTML

    if episodes[0].frames is None:
        body = _iframes(episodes)
    else:
        from .anim2d import animate, player

        body = '<div style="display:flex;gap:8px">' + "".join(
            f'<div style="flex:1">{player(animate(ep.frames, title=ep.method, goals=True)).data}</div>'
            for ep in episodes) + "</div>"
    return HTML(f'<div><p style="font-family:sans-serif">{html.escape(_title(episodes))}</p>{body}'
                f"{_table(episodes)}</div>")


class Playground:
    """The widgets, and the two episodes they show (``episodes``, ``None`` before the first run).

    ``scenario``, ``team_size``, ``seed``, ``method_a``, ``method_b`` choose a pair;
    ``run_button`` (or :meth:`run`) records it; ``step`` (driven by ``play`` in a notebook)
    picks the step shown in ``view`` (2-D: a PNG ``Image``; drones: ``view3d``, an ``HTML``
    with both meshcat pages) and in ``table``; ``metrics`` holds the two :func:`metrics_at`
    dicts shown; ``status`` says what ran, or why it could not. ``overrides`` are scenario
    overrides kept for every run (``num_agents`` belongs to ``team_size``). ``box`` is the
    layout; a Playground displays as it, with a still of the current step for viewers
    without a widget manager.
    """

    def __init__(self, scenario: str = "mpe-5", team_size: int | None = None, seed: int = 0,
                 method_a: str = "h-greedy", method_b: str = "masp", overrides=None, run: bool = True):
        import ipywidgets as W

        if not isinstance(scenario, str):
            raise ValueError(f"scenario: expected a preset name, one of {scenario_names()}, got {scenario!r}")
        _check(method_a, method_b, seed)
        overrides = dict(overrides or {})
        sc = _scenario(scenario, team_size, overrides)
        overrides.pop("num_agents", None)  # the team_size widget holds it from now on
        self.overrides, self.episodes, self.metrics = overrides, None, None
        self._fig = self._scenes = None
        self.scenario = W.Dropdown(options=scenario_names(), value=scenario, description="scenario")
        self.team_size = W.Dropdown(options=sorted(set(team_sizes(scenario, overrides)) | {sc.num_agents}),
                                    value=sc.num_agents, description="agents")
        self.seed = W.BoundedIntText(value=int(seed), min=0, max=2**31 - 1, description="seed")
        self.method_a = W.Dropdown(options=method_names(), value=method_a, description="method A")
        self.method_b = W.Dropdown(options=method_names(), value=method_b, description="method B")
        self.run_button = W.Button(description="run", button_style="primary")
        self.step = W.IntSlider(value=0, min=0, max=sc.horizon, description="step", continuous_update=True)
        self.play = W.Play(value=0, min=0, max=sc.horizon, interval=250)
        W.jslink((self.play, "value"), (self.step, "value"))
        self.view, self.view3d = W.Image(format="png"), W.HTML()
        self.table, self.status = W.HTML(), W.HTML()
        self.slider_note = W.HTML()  # drones: what the slider moves (the metrics, not the 3-D views)
        self.scenario.observe(lambda change: self._on_scenario(change["new"]), names="value")
        self.step.observe(lambda change: self._show(change["new"]), names="value")
        self.run_button.on_click(self.run)
        self.box = W.VBox([W.HBox([self.scenario, self.team_size, self.seed]),
                           W.HBox([self.method_a, self.method_b, self.run_button]), self.status,
                           W.HBox([self.play, self.step, self.slider_note]), self.view, self.view3d, self.table])
        if run:
            self.run()

    def _on_scenario(self, name: str) -> None:
        try:
            sizes = team_sizes(name, self.overrides)
        except ValueError as e:  # the kept overrides do not fit this scenario
            self.status.value = _error(e)
            return
        preset = SCENARIOS[name].num_agents
        self.team_size.options = sizes
        self.team_size.value = preset if preset in sizes else sizes[0]

    def run(self, _button=None) -> tuple[Episode, Episode] | None:
        """Record the chosen pair and show its first step; a bad choice is reported in ``status``."""
        started = time.perf_counter()
        try:
            episodes = rollout_pair(self.scenario.value, self.team_size.value, self.seed.value, self.method_a.value,
                                    self.method_b.value, self.overrides)
        except ValueError as e:
            self.status.value = _error(e)
            return None
        self.episodes = None  # rewinding the slider below draws nothing
        self.step.value = self.play.value = 0
        self.step.max = self.play.max = episodes[0].horizon
        particle = episodes[0].frames is not None
        self._fig, self._scenes = self._figure(episodes) if particle else (None, None)
        self.view.layout.display = None if particle else "none"
        self.view3d.layout.display = "none" if particle else None
        self.view3d.value = "" if particle else _iframes(episodes)
        self.step.description = "step" if particle else "metrics at"
        self.slider_note.value = "" if particle else f"<i>{html.escape(SLIDER_NOTE_3D)}</i>"
        self.episodes = episodes
        self._show(0)
        self.status.value = f"{html.escape(_title(episodes))} — recorded in {time.perf_counter() - started:.1f} s"
        return episodes

    @staticmethod
    def _figure(episodes):
        from matplotlib.figure import Figure

        from .anim2d import Scene, _magnification, legend

        fig = Figure(figsize=(10.0, 5.6), dpi=80)
        scenes = []
        for i, ep in enumerate(episodes):
            ax = fig.add_axes((0.02 + 0.5 * i, 0.12, 0.46, 0.8))
            first = ep.frames[0]
            scenes.append(Scene(ax, first, goals=True, title=ep.method, magnify=_magnification(ax, first)))
        legend(fig, varying=episodes[0].scenario.varying, goals=True, trails=True, loc="lower center", ncol=5,
               bbox_to_anchor=(0.5, 0.0), columnspacing=1.2, handletextpad=0.4)
        return fig, scenes

    def _show(self, t: int) -> None:
        if self.episodes is None:
            return
        t = min(int(t), self.episodes[0].horizon)
        if self._scenes is not None:
            for scene, ep in zip(self._scenes, self.episodes):
                trail = np.stack([f["agent_pos"] for f in ep.frames[max(0, t - TRAIL):t]]) if t else None
                scene.update(ep.frames[t], trail)
            buffer = io.BytesIO()
            self._fig.savefig(buffer, format="png")
            self.view.value = buffer.getvalue()
        self.metrics = tuple(metrics_at(ep, t) for ep in self.episodes)
        self.table.value = _table(self.episodes, t)

    def _repr_mimebundle_(self, **kwargs):
        bundle = self.box._repr_mimebundle_(**kwargs)
        if self.episodes is not None:
            still = (f'<img src="data:image/png;base64,{base64.b64encode(self.view.value).decode("ascii")}">'
                     if self._scenes is not None else self.view3d.value)
            bundle["text/html"] = f"<div>{self.status.value}{still}{self.table.value}</div>"
        return bundle


def _widgets_render() -> bool:
    """True inside a notebook kernel that is not run by a test (nbval's kernels inherit pytest's variable)."""
    try:
        import ipywidgets  # noqa: F401
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and "IPKernelApp" in shell.config and "PYTEST_CURRENT_TEST" not in os.environ


def show(scenario: str = "mpe-5", team_size: int | None = None, seed: int = 0, method_a: str = "h-greedy",
         method_b: str = "masp", overrides=None, widgets: bool | None = None):
    """A :class:`Playground` (``widgets`` True) or the :func:`static` page of the pair (False).

    ``widgets`` ``None`` picks: the playground in a live notebook kernel, the static page
    elsewhere (plain Python, a terminal, a notebook run by nbval).
    """
    if widgets is None:
        widgets = _widgets_render()
    if widgets:
        return Playground(scenario, team_size, seed, method_a, method_b, overrides)
    return static(rollout_pair(scenario, team_size, seed, method_a, method_b, overrides))
