"""2-D playback of particle-world episodes with matplotlib.

:func:`record` runs one episode of a policy and keeps, per step, a *frame*: a dict of
numpy arrays for one world of the batch. :func:`draw_frame` draws a frame on an axes (a
:class:`Scene`, whose ``update`` shows another frame); :func:`draw_obs` draws one world of
an observation directly (a snapshot, no policy or recording needed); :func:`legend` adds
the key of the colours to an axes or a figure. :func:`animate` turns frames into a
``matplotlib.animation.FuncAnimation``, :func:`player` embeds it in a notebook as an
HTML5 video that needs no network, and :func:`save` writes it as ``.gif`` (pillow) or
``.mp4`` (the ffmpeg binary shipped by ``imageio-ffmpeg``).

What a frame shows, on the ``[-ws/2, ws/2]`` map:

* landmarks — small rings, filled green while covered, grey once reached (varying teams);
* obstacles — dark grey discs;
* agents — blue, pale dashed outlines once dropped from the team, red for the step in
  which they are in contact; with ``goals=True`` a dotted line joins each agent to its
  current goal (:func:`current_goals`: what the policy exposes), and an agent without
  one is light blue;
* a title with the method (when given), the step, the success rate so far (fixed teams:
  covered now; varying teams: ever reached) and the collision rate so far, as in
  :mod:`masp_lite.evaluation`.

Still pictures (:func:`draw_frame`, :func:`draw_obs`) draw every body to scale. An
animation shows the whole map at once, where a 0.1 m agent on the 20 m map of ``mpe-50``
would be a dot: :func:`animate` magnifies the bodies so that an agent is at least
:data:`MIN_AGENT_PT` points wide on screen (positions stay exact; the x-label says how
much), and draws a short fading trail behind every agent.

Frame keys: ``agent_pos`` (N, 2), ``landmark_pos`` (L, 2), ``obstacle_pos`` (K, 2),
``alive`` (N,), ``covered`` (L,), ``reached`` (L,), ``agent_collisions`` (N,),
``collisions`` (events so far), ``assignment`` (N,) or ``None``, ``t``, ``horizon``,
``varying``, ``world_size`` and the three radii.
"""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib
import numpy as np
import torch

from ..files import atomic_target

__all__ = ["record", "episode_numbers", "CONTROLS_PX", "draw_frame", "draw_obs", "frame_from_obs", "current_goals",
           "legend", "animate", "player",
           "save", "Scene", "COLOURS", "MIN_AGENT_PT"]

COLOURS = {"agent": "#1f77b4", "idle": "#9ecae1", "dropped": "#d9d9d9", "hit": "#d62728",
           "landmark": "#31a354", "reached": "#bdbdbd", "obstacle": "#525252", "trail": "#1f77b4"}

#: Smallest on-screen width of an agent in an animation, in points (1/72 inch).
MIN_AGENT_PT = 7.5


def current_goals(policy) -> torch.Tensor | None:
    """The goal index per agent (B, N) that ``policy`` exposes (``-1``: none), or ``None``.

    Read, not asked for: ``policy.assignment`` (``h-greedy`` and its variants, the (H)
    planners: the latest Hungarian assignment) or, failing that, ``policy.goals`` when it
    is an integer tensor (MASP: the Goal Matcher's latest picks). A policy without either
    (``random``) has no goals to draw.
    """
    for name in ("assignment", "goals"):
        value = getattr(policy, name, None)
        if torch.is_tensor(value) and value.dim() == 2 and not value.is_floating_point():
            return value
    return None


def _frame(world, policy, obs, info, b: int, collisions_so_far: int) -> dict:
    sc = world.scenario
    np_ = lambda x: x[b].detach().cpu().numpy().copy()  # noqa: E731
    goals = current_goals(policy)
    return {
        "agent_pos": np_(obs["agent_pos"])[:, :2], "landmark_pos": np_(obs["landmark_pos"])[:, :2],
        "obstacle_pos": np_(obs["obstacle_pos"])[:, :2] if "obstacle_pos" in obs else np.zeros((0, 2)),
        "alive": np_(obs["alive"]), "covered": np_(obs["covered"]), "reached": np_(obs["reached"]),
        "agent_collisions": np_(info["agent_collisions"]) if info is not None and "agent_collisions" in info
        else np.zeros(world.num_agents, dtype=np.int64),
        "collisions": int(collisions_so_far),
        "assignment": None if goals is None else np_(goals),
        "t": int(obs["t"][b]), "horizon": int(world.horizon), "varying": bool(sc.varying),
        "world_size": float(sc.world_size), "agent_radius": sc.agent_radius,
        "landmark_radius": sc.landmark_radius, "obstacle_radius": sc.obstacle_radius,
    }


def record(world, policy, seed: int | None = 0, env_index: int = 0) -> list[dict]:
    """Run one episode of ``policy`` on ``world`` (all its worlds step) and keep world ``env_index``.

    Returns ``horizon + 1`` frames (the reset state, then one per step). The goals shown
    with a frame are the ones the policy acted on to leave that state, so the first
    frame has none unless the policy set them in ``reset``.
    """
    if not 0 <= env_index < world.num_envs:
        raise ValueError(f"env_index: expected an index in [0, {world.num_envs}), got {env_index}")
    obs = world.reset(seed=seed)
    policy.reset(obs)
    frames = [_frame(world, policy, obs, None, env_index, 0)]
    collisions = 0
    while not bool(world.done.all()):
        obs, info = world.step(policy.act(obs))
        collisions += int(info["collisions"][env_index])
        frames.append(_frame(world, policy, obs, info, env_index, collisions))
    return frames


class Scene:
    """The artists of one axes, built once and updated per frame (fast enough for N = 50).

    Each kind of body is one ``EllipseCollection`` sized in data units (``magnify`` times
    the true radius; 1: to scale); goal lines and trails are ``LineCollection`` objects.
    :meth:`update` moves and recolours them instead of redrawing, which keeps a 50-agent
    animation to a few seconds. ``goals`` draws the goal lines; ``title`` (e.g. the method's
    name) starts the title line.
    """

    def __init__(self, ax, frame: dict, *, goals: bool = False, magnify: float = 1.0, title: str | None = None):
        from matplotlib.collections import EllipseCollection, LineCollection

        if not isinstance(magnify, (int, float)) or isinstance(magnify, bool) or not magnify >= 1:
            raise ValueError(f"magnify: expected a number >= 1 (1: bodies to scale), got {magnify!r}")
        self.ax, self.goals, self.magnify, self.label = ax, bool(goals), float(magnify), title
        ax.clear()
        half = frame["world_size"] / 2
        ax.set_xlim(-half, half)
        ax.set_ylim(-half, half)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        if self.magnify > 1:
            ax.set_xlabel(f"bodies drawn {self.magnify:g}× their size", fontsize=8, color="0.4")

        def bodies(pos, radius, zorder, **kw):
            d = np.full(len(pos), 2 * radius * self.magnify)
            coll = EllipseCollection(d, d, np.zeros(len(pos)), units="xy", offsets=pos.reshape(-1, 2),
                                     offset_transform=ax.transData, zorder=zorder, **kw)
            ax.add_collection(coll)
            return coll

        self.obstacles = bodies(frame["obstacle_pos"], frame["obstacle_radius"], 1, facecolors=COLOURS["obstacle"])
        self.trails = LineCollection([], linewidths=1.5, zorder=2)
        ax.add_collection(self.trails)
        self.lines = LineCollection([], linestyles=":", linewidths=0.8, colors=COLOURS["agent"], zorder=2)
        ax.add_collection(self.lines)
        self.agents = bodies(frame["agent_pos"], frame["agent_radius"], 3, alpha=0.85, linewidths=1.0)
        # landmarks on top, so a covered one shows green under its agent
        self.landmarks = bodies(frame["landmark_pos"], frame["landmark_radius"], 4,
                                edgecolors=COLOURS["landmark"], linewidths=1.0)
        self.title = ax.set_title("", fontsize=10)
        self.update(frame)

    def update(self, frame: dict, trail: np.ndarray | None = None) -> list:
        """Show ``frame``, with ``trail`` (k, N, 2): earlier positions, oldest first; returns the changed artists."""
        alive, hit = frame["alive"].astype(bool), frame["agent_collisions"] > 0
        assignment = frame.get("assignment") if self.goals else None
        has_goal = np.ones_like(alive) if assignment is None else assignment >= 0
        face = np.where(hit, COLOURS["hit"], np.where(has_goal, COLOURS["agent"], COLOURS["idle"]))
        self.agents.set_offsets(frame["agent_pos"])
        self.agents.set_facecolors([c if a else "none" for c, a in zip(face, alive)])
        self.agents.set_edgecolors([c if a else COLOURS["dropped"] for c, a in zip(face, alive)])
        self.agents.set_linestyles(["-" if a else "--" for a in alive])
        covered, reached = frame["covered"].astype(bool), frame["reached"].astype(bool)
        self.landmarks.set_facecolors([COLOURS["landmark"] if c else COLOURS["reached"]
                                       if (r and frame["varying"]) else "none" for c, r in zip(covered, reached)])
        segments = []
        if assignment is not None:
            segments = [(p, frame["landmark_pos"][g]) for p, g, a in
                        zip(frame["agent_pos"], assignment, alive) if a and g >= 0]
        self.lines.set_segments(segments)
        self._set_trails(frame, trail, alive)
        done = reached if frame["varying"] else covered
        t = frame["t"]
        sr = float(np.mean(done)) if len(done) else 1.0
        cr = frame["collisions"] / t if t else 0.0
        head = f"{self.label}   " if self.label else ""
        self.title.set_text(f"{head}t = {t}/{frame['horizon']}   SR = {sr:.2f}   CR = {cr:.2f}")
        return [self.agents, self.landmarks, self.lines, self.trails, self.title]

    def _set_trails(self, frame, trail, alive):
        if trail is None or len(trail) == 0:
            self.trails.set_segments([])
            return
        path = np.concatenate([np.asarray(trail, dtype=float), frame["agent_pos"][None]], axis=0)  # (k + 1, N, 2)
        k = len(path) - 1
        segments = np.stack([path[:-1], path[1:]], axis=2)[:, alive]  # (k, alive, 2 points, 2)
        rgba = np.tile(matplotlib.colors.to_rgba(COLOURS["trail"]), (k, 1))
        rgba[:, 3] = 0.7 * np.arange(1, k + 1) / k  # older segments fade out
        self.trails.set_segments(segments.reshape(-1, 2, 2))
        self.trails.set_colors(np.repeat(rgba, segments.shape[1], axis=0))


def draw_frame(ax, frame: dict, goals: bool = False) -> Scene:
    """Draw one frame on ``ax`` (cleared first), bodies to scale, goal lines if ``goals``; returns the Scene."""
    return Scene(ax, frame, goals=goals)


def frame_from_obs(obs: dict, scenario, env: int = 0) -> dict:
    """The frame of world ``env`` of a batched observation ``obs`` of ``scenario``.

    A snapshot: no goals (``assignment`` is ``None``), no contacts and no collisions so
    far, since an observation does not carry them. Positions keep their first two axes.
    """
    batch = obs["agent_pos"].shape[0]
    if not 0 <= env < batch:
        raise ValueError(f"env: expected an index in [0, {batch}), got {env}")
    np_ = lambda key: obs[key][env].detach().cpu().numpy().copy()  # noqa: E731
    return {
        "agent_pos": np_("agent_pos")[:, :2], "landmark_pos": np_("landmark_pos")[:, :2],
        "obstacle_pos": np_("obstacle_pos")[:, :2] if "obstacle_pos" in obs else np.zeros((0, 2)),
        "alive": np_("alive"), "covered": np_("covered"), "reached": np_("reached"),
        "agent_collisions": np.zeros(obs["agent_pos"].shape[1], dtype=np.int64), "collisions": 0,
        "assignment": None, "t": int(obs["t"][env]), "horizon": int(scenario.horizon),
        "varying": bool(scenario.varying), "world_size": float(scenario.world_size),
        "agent_radius": scenario.agent_radius, "landmark_radius": scenario.landmark_radius,
        "obstacle_radius": scenario.obstacle_radius,
    }


def draw_obs(obs: dict, scenario, env: int = 0, ax=None, title: str | None = None) -> Scene:
    """Draw world ``env`` of an observation on ``ax`` (default: the current axes).

    Chapter 01's picture of spawns, contacts and team changes without recording an
    episode: the same bodies and colours as :func:`draw_frame` (dropped agents as pale
    dashed outlines). ``title`` replaces the step/SR title. Returns the :class:`Scene`;
    its ``ax`` takes further plotting (paths, limits); :func:`legend` adds the key.
    """
    import matplotlib.pyplot as plt

    scene = Scene(plt.gca() if ax is None else ax, frame_from_obs(obs, scenario, env))
    if title is not None:
        scene.title.set_text(title)
    return scene


def legend(target, *, contacts: bool = True, varying: bool = False, goals: bool = False, trails: bool = False,
           **kwargs):
    """The key of :class:`Scene`'s colours on ``target`` (an axes or a figure); returns the ``Legend``.

    Always: agents, landmarks, covered landmarks, obstacles; ``contacts``: agents in
    contact; ``varying``: dropped agents and landmarks reached earlier; ``goals``: agents
    without a goal and the goal lines; ``trails``: the trails. ``kwargs`` go to
    ``target.legend`` (e.g. ``loc``, ``ncol``, ``bbox_to_anchor``).
    """
    from matplotlib.lines import Line2D

    def disc(label, face, edge=None, size=8):
        return Line2D([], [], ls="none", marker="o", ms=size, mfc=face, mec=edge or face, mew=1.0, label=label)

    handles = [disc("agent", COLOURS["agent"])]
    if goals:
        handles.append(disc("agent without a goal", COLOURS["idle"]))
    if contacts:
        handles.append(disc("agent in contact", COLOURS["hit"]))
    if varying:
        handles.append(disc("dropped agent", "none", COLOURS["dropped"]))
    handles += [disc("landmark", "none", COLOURS["landmark"], 6), disc("covered landmark", COLOURS["landmark"], size=6)]
    if varying:
        handles.append(disc("reached earlier", COLOURS["reached"], COLOURS["landmark"], 6))
    handles.append(disc("obstacle", COLOURS["obstacle"]))
    if goals:
        handles.append(Line2D([], [], ls=":", lw=1.2, color=COLOURS["agent"], label="agent → its goal"))
    if trails:
        handles.append(Line2D([], [], ls="-", lw=1.2, color=COLOURS["trail"], alpha=0.5, label="recent path"))
    return target.legend(handles=handles, **{"fontsize": 8, "frameon": False, **kwargs})


def _magnification(ax, frame: dict) -> float:
    """How much larger than to scale the bodies must be for an agent of :data:`MIN_AGENT_PT` on ``ax``."""
    box = ax.get_position(original=True)  # the square map fills the shorter side of the axes box
    side_pt = 72 * min(box.width * ax.figure.get_figwidth(), box.height * ax.figure.get_figheight())
    agent_pt = 2 * frame["agent_radius"] * side_pt / frame["world_size"]
    return max(1.0, math.ceil(2 * MIN_AGENT_PT / agent_pt) / 2)  # in steps of 0.5, to read "2×" rather than "1.97×"


#: Height (CSS pixels) a browser's ``<video>`` control bar covers at the bottom of the picture: the
#: animation leaves that strip empty, so the controls never hide the legend.
CONTROLS_PX = 56


def episode_numbers(frames: list[dict]) -> dict:
    """SR, Steps and CR of the recorded episode ``frames`` (as :mod:`masp_lite.evaluation` computes them).

    SR: the share of landmarks covered at the end (reached at some point, in a varying team);
    Steps: the first step at which every landmark was, or the horizon; CR: collisions per step.
    """
    if not frames:
        raise ValueError("frames: expected at least one frame (see record())")
    last = frames[-1]
    key = "reached" if last["varying"] else "covered"
    solved = [f["t"] for f in frames if len(f[key]) == 0 or bool(np.all(f[key]))]
    return {"sr": float(np.mean(last[key])) if len(last[key]) else 1.0,
            "steps": int(solved[0]) if solved else int(last["horizon"]),
            "cr": last["collisions"] / last["t"] if last["t"] else 0.0}


def animate(frames: list[dict], interval: int = 150, figsize=(6.0, 7.2), *, title: str | None = None,
            goals: bool = False, trail: int = 6, legend_below: bool = True, magnify: float | None = None):
    """A ``FuncAnimation`` of ``frames`` (``interval`` ms per frame) on the whole map.

    ``title`` (e.g. the method's name) starts every title line; ``goals`` draws a line
    from each agent to its current goal; ``trail`` is the number of earlier frames each
    agent's trail spans (0: none); ``legend_below`` puts the colour key under the map;
    ``magnify`` scales the bodies (default: so that an agent is :data:`MIN_AGENT_PT`
    points wide). With ``legend_below``, the bottom :data:`CONTROLS_PX` pixels stay empty:
    the video player's control bar covers them, not the legend. The figure is closed, so
    notebooks show only the animation (``player(anim)``); ``anim.scene`` is its :class:`Scene`.
    """
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    if not frames:
        raise ValueError("frames: expected at least one frame (see record())")
    if not isinstance(trail, int) or isinstance(trail, bool) or trail < 0:
        raise ValueError(f"trail: expected a number of frames >= 0, got {trail!r}")
    fig = plt.figure(figsize=figsize)
    controls = CONTROLS_PX / (fig.get_figheight() * fig.dpi) if legend_below else 0.0  # the player's bar
    bottom = (0.12 + controls) if legend_below else 0.04
    ax = fig.add_axes((0.03, bottom, 0.94, 0.925 - bottom))
    scene = Scene(ax, frames[0], goals=goals, title=title,
                  magnify=_magnification(ax, frames[0]) if magnify is None else magnify)
    if legend_below:
        legend(fig, varying=frames[0]["varying"], goals=goals, trails=trail > 0, loc="lower center", ncol=4,
               bbox_to_anchor=(0.5, controls), columnspacing=1.2, handletextpad=0.4)
    positions = np.stack([f["agent_pos"] for f in frames])

    def show(i):
        return scene.update(frames[i], positions[max(0, i - trail):i] if trail else None)

    anim = FuncAnimation(fig, show, frames=len(frames), interval=interval, repeat=False)
    anim.scene = scene
    plt.close(fig)
    return anim


def _ffmpeg() -> None:
    import imageio_ffmpeg  # the ffmpeg binary ships with the wheel: no system ffmpeg needed
    matplotlib.rcParams["animation.ffmpeg_path"] = imageio_ffmpeg.get_ffmpeg_exe()


def player(anim):
    """``anim`` as an ``IPython.display.HTML`` video player for a notebook cell.

    An HTML5 ``<video>`` whose H.264 file is embedded as a data URL (matplotlib's
    ``to_html5_video``, encoded by imageio-ffmpeg's ffmpeg): the browser's own controls,
    nothing fetched from the network — unlike ``to_jshtml``, whose buttons load their icons
    from a CDN and stay blank offline.
    """
    from IPython.display import HTML

    _ffmpeg()
    return HTML(anim.to_html5_video())


def save(anim, path, fps: int | None = None) -> Path:
    """Write ``anim`` to ``path``: ``.gif`` with pillow, ``.mp4`` with imageio-ffmpeg's ffmpeg."""
    from matplotlib.animation import FFMpegWriter, PillowWriter

    path = Path(path)
    fps = fps or max(1, round(1000 / getattr(anim, "_interval", 150)))
    suffix = path.suffix.lower()
    if suffix == ".gif":
        writer = PillowWriter(fps=fps)
    elif suffix == ".mp4":
        _ffmpeg()
        writer = FFMpegWriter(fps=fps)
    else:
        raise ValueError(f"{path.name}: expected a .gif or .mp4 file name")
    with atomic_target(path) as tmp:  # the encoder writes a temporary file beside it, renamed when whole
        anim.save(str(tmp), writer=writer)
    return path
