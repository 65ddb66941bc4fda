"""2-D playback of particle-world episodes with matplotlib.

:func:`record` runs one episode of a policy and keeps, per step, a *frame*: a dict of
numpy arrays for one world of the batch. :func:`draw_frame` draws a frame on an axes (a
:class:`Scene`, whose ``update`` shows another frame); :func:`draw_obs` draws one world of
an observation directly (a snapshot, no policy or recording needed),
:func:`animate` turns frames into a ``matplotlib.animation.FuncAnimation`` (in JupyterLab:
``IPython.display.HTML(anim.to_jshtml())``), and :func:`save` writes it as ``.gif``
(pillow) or ``.mp4`` (the ffmpeg binary shipped by ``imageio-ffmpeg``).

What a frame shows, all circles to scale on the ``[-ws/2, ws/2]`` map:

* landmarks — small rings, filled green while covered, grey once reached (varying teams);
* obstacles — dark grey discs;
* agents — blue when they have a goal (a thin dotted line joins agent and goal when the
  policy exposes ``assignment``), light blue without one, pale dashed outlines once
  dropped from the team; red for the step in which they are in contact;
* a title with the step, the success rate so far (fixed teams: covered now; varying
  teams: ever reached) and the collision rate so far, as in :mod:`masp_lite.evaluation`.

Frame keys: ``agent_pos`` (N, 2), ``landmark_pos`` (L, 2), ``obstacle_pos`` (K, 2),
``alive`` (N,), ``covered`` (L,), ``reached`` (L,), ``agent_collisions`` (N,),
``collisions`` (events so far), ``assignment`` (N,) or ``None``, ``t``, ``horizon``,
``varying``, ``world_size`` and the three radii.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np
import torch

__all__ = ["record", "draw_frame", "draw_obs", "frame_from_obs", "animate", "save", "Scene"]

COLOURS = {"agent": "#1f77b4", "idle": "#9ecae1", "dropped": "#d9d9d9", "hit": "#d62728",
           "landmark": "#31a354", "reached": "#bdbdbd", "obstacle": "#525252"}


def _frame(world, policy, obs, info, b: int, collisions_so_far: int) -> dict:
    sc = world.scenario
    np_ = lambda x: x[b].detach().cpu().numpy().copy()  # noqa: E731
    assignment = getattr(policy, "assignment", None)
    return {
        "agent_pos": np_(obs["agent_pos"])[:, :2], "landmark_pos": np_(obs["landmark_pos"])[:, :2],
        "obstacle_pos": np_(obs["obstacle_pos"])[:, :2] if "obstacle_pos" in obs else np.zeros((0, 2)),
        "alive": np_(obs["alive"]), "covered": np_(obs["covered"]), "reached": np_(obs["reached"]),
        "agent_collisions": np_(info["agent_collisions"]) if info is not None and "agent_collisions" in info
        else np.zeros(world.num_agents, dtype=np.int64),
        "collisions": int(collisions_so_far),
        "assignment": np_(assignment) if torch.is_tensor(assignment) else None,
        "t": int(obs["t"][b]), "horizon": int(world.horizon), "varying": bool(sc.varying),
        "world_size": float(sc.world_size), "agent_radius": sc.agent_radius,
        "landmark_radius": sc.landmark_radius, "obstacle_radius": sc.obstacle_radius,
    }


def record(world, policy, seed: int | None = 0, env_index: int = 0) -> list[dict]:
    """Run one episode of ``policy`` on ``world`` (all its worlds step) and keep world ``env_index``.

    Returns ``horizon + 1`` frames (the reset state, then one per step). The assignment
    shown with a frame is the one the policy acted on to leave that state, so the first
    frame has none unless the policy set it in ``reset``.
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

    Each kind of body is one ``EllipseCollection`` sized in data units, so circles stay to
    scale at any zoom; assignment lines are one ``LineCollection``. :meth:`update` moves and
    recolours them instead of redrawing, which keeps a 50-agent animation to a few seconds.
    """

    def __init__(self, ax, frame: dict):
        from matplotlib.collections import EllipseCollection, LineCollection

        self.ax = ax
        ax.clear()
        half = frame["world_size"] / 2
        ax.set_xlim(-half, half)
        ax.set_ylim(-half, half)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])

        def bodies(pos, radius, zorder, **kw):
            d = np.full(len(pos), 2 * radius)
            coll = EllipseCollection(d, d, np.zeros(len(pos)), units="xy", offsets=pos.reshape(-1, 2),
                                     offset_transform=ax.transData, zorder=zorder, **kw)
            ax.add_collection(coll)
            return coll

        self.obstacles = bodies(frame["obstacle_pos"], frame["obstacle_radius"], 1, facecolors=COLOURS["obstacle"])
        self.lines = LineCollection([], linestyles=":", linewidths=0.8, colors=COLOURS["agent"], zorder=2)
        ax.add_collection(self.lines)
        self.agents = bodies(frame["agent_pos"], frame["agent_radius"], 3, alpha=0.85, linewidths=1.0)
        # landmarks on top, so a covered one shows green under its agent
        self.landmarks = bodies(frame["landmark_pos"], frame["landmark_radius"], 4,
                                edgecolors=COLOURS["landmark"], linewidths=1.0)
        self.title = ax.set_title("", fontsize=10)
        self.update(frame)

    def update(self, frame: dict) -> list:
        """Show ``frame``; returns the artists that changed."""
        alive, hit = frame["alive"].astype(bool), frame["agent_collisions"] > 0
        assignment = frame.get("assignment")
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
        done = reached if frame["varying"] else covered
        t = frame["t"]
        sr = float(np.mean(done)) if len(done) else 1.0
        cr = frame["collisions"] / t if t else 0.0
        self.title.set_text(f"t = {t}/{frame['horizon']}   SR = {sr:.2f}   CR = {cr:.2f}")
        return [self.agents, self.landmarks, self.lines, self.title]


def draw_frame(ax, frame: dict) -> Scene:
    """Draw one frame on ``ax`` (cleared first); returns the :class:`Scene` for later updates."""
    return Scene(ax, frame)


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
    its ``ax`` takes further plotting (paths, limits).
    """
    import matplotlib.pyplot as plt

    scene = Scene(plt.gca() if ax is None else ax, frame_from_obs(obs, scenario, env))
    if title is not None:
        scene.title.set_text(title)
    return scene


def animate(frames: list[dict], interval: int = 150, figsize=(5.0, 5.0)):
    """A ``FuncAnimation`` of ``frames`` (``interval`` ms per frame); the figure is closed
    so notebooks show only the animation (``HTML(anim.to_jshtml())``)."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    if not frames:
        raise ValueError("frames: expected at least one frame (see record())")
    fig, ax = plt.subplots(figsize=figsize)
    fig.subplots_adjust(left=0.02, right=0.98, bottom=0.02, top=0.92)
    scene = Scene(ax, frames[0])
    anim = FuncAnimation(fig, lambda i: scene.update(frames[i]), frames=len(frames),
                         interval=interval, repeat=False)
    plt.close(fig)
    return anim


def save(anim, path, fps: int | None = None) -> Path:
    """Write ``anim`` to ``path``: ``.gif`` with pillow, ``.mp4`` with imageio-ffmpeg's ffmpeg."""
    from matplotlib.animation import FFMpegWriter, PillowWriter

    path = Path(path)
    fps = fps or max(1, round(1000 / getattr(anim, "_interval", 150)))
    suffix = path.suffix.lower()
    if suffix == ".gif":
        writer = PillowWriter(fps=fps)
    elif suffix == ".mp4":
        import imageio_ffmpeg  # the ffmpeg binary ships with the wheel: no system ffmpeg needed
        matplotlib.rcParams["animation.ffmpeg_path"] = imageio_ffmpeg.get_ffmpeg_exe()
        writer = FFMpegWriter(fps=fps)
    else:
        raise ValueError(f"{path.name}: expected a .gif or .mp4 file name")
    path.parent.mkdir(parents=True, exist_ok=True)
    anim.save(str(path), writer=writer)
    return path
