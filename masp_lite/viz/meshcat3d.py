"""3-D playback of drone episodes with meshcat: live in JupyterLab, or as a standalone page.

An episode is recorded once (:func:`record_episode`: positions, attitudes, who is flying,
which landmarks are reached, every ``stride`` steps), then drawn as a meshcat scene:

* each drone: a hub, four arms and four rotor discs (red: spin −1, blue: spin +1), a
  colour of its own on the hub; its whole path as a thin line of that colour (the trail);
  drawn :func:`drone_scale` times its size on large maps (2x on drone-20's 16 m map), so
  that 20 drones read from the default camera, which sits close enough to see the map whole;
* landmarks: a ball of the scenario's radius inside a translucent green marker large
  enough to see from the default camera (:func:`marker_radius`: a 0.05 m ball on a 16 m
  map is a pixel), on a thin stem down to the floor so its height reads; a bright halo
  appears when one is reached;
* crashes: a red ball appears where a drone crashed, and the drone disappears (a drone
  dropped by a team-size change disappears without one);
* the floor: a grey tile of the map's size.

The motion is a meshcat ``Animation`` (position, quaternion and scale tracks), so the
viewer plays it by itself (its "Animations" panel has play / pause / speed). On the
standalone page the controls open with the Scene tree folded and the Animations panel open,
and the panel scrolls, so play / pause stay in reach in a 400-px notebook cell.

Two ways to show it:

* :func:`play_to_html` / :func:`episode_html` — a **standalone HTML page**: meshcat's own
  static viewer (``main.min.js`` shipped in the ``meshcat`` package) followed by the
  scene's commands, embedded as base64 blobs exactly as meshcat's server writes them for
  its ``static_html``, and an on-screen key (the method, the scenario, what each colour
  means). No server is started: the commands are recorded by a window object that only
  stores them (:class:`RecordingWindow`). :func:`notebook_html` wraps the page in an
  ``<iframe srcdoc=…>`` for a notebook cell: it needs no kernel-side server, so it still
  shows when the saved notebook is reopened.
* :class:`LiveViewer` — a **meshcat server** bound to ``127.0.0.1`` (meshcat's own
  subprocess), as a context manager that kills it on exit, so nothing keeps running after
  a notebook or a test: ``with LiveViewer() as v: v.show(episode); print(v.web_url)``.
  Its page lives only as long as the server: a notebook output of it
  (:meth:`LiveViewer.cell`) is a dead frame once the server stops.

Hand-written here: only the scene layout and the recording window; geometry, animation
encoding and the viewer are meshcat's.
"""
from __future__ import annotations

import base64
import html as html_lib
import os
import warnings

import numpy as np

from ..files import atomic_write

__all__ = ["record_episode", "build_scene", "episode_html", "key_html", "play_to_html", "notebook_html",
           "marker_radius", "drone_scale", "RecordingWindow", "LiveViewer"]

_FPS_STEPS = 2  # env steps per animation frame by default (0.032 s of flight)
LANDMARK, REACHED, CRASH = 0x228833, 0x66ee44, 0xee2222  # the scene's colours, named in the on-screen key
SPIN_MINUS, SPIN_PLUS = 0xdd4433, 0x3377dd                 # rotor discs by spin direction


def marker_radius(scenario) -> float:
    """Radius (m) of a landmark's translucent marker: visible from the default camera on any map.

    The camera sees the whole map, so the marker grows with it: 1/80 of the map side, at
    least 0.15 m (and never smaller than the landmark itself).
    """
    return max(0.15, scenario.world_size / 80, 2 * scenario.landmark_radius)


def drone_scale(scenario) -> float:
    """How much larger than life the drones are drawn: 1 on small maps, 2 on drone-20's 16 m map.

    A drone is about 0.5 m across; seen whole from the default camera, a 16 m map leaves it a
    few pixels, so the model grows with the map (1/8 of the side per metre of drone, in steps
    of 0.5). The key says so whenever it is more than 1.
    """
    return max(1.0, round(float(scenario.world_size) / 8 * 2) / 2)


def _meshcat():
    with warnings.catch_warnings():  # pyzmq's DeprecationWarning on import, harmless
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat
        import meshcat.animation
        import meshcat.geometry
    return meshcat


def record_episode(method, scenario, seed: int = 0, stride: int = _FPS_STEPS, **overrides) -> dict:
    """Run one episode of ``method`` (a registered name or a ``factory(world)``) and keep what is drawn.

    Returns numpy arrays: ``pos`` (T, N, 3), ``quat`` (T, N, 4), ``alive`` (T, N),
    ``reached`` (T, N), ``landmark_pos`` (N, 3), plus ``dt`` (seconds per frame),
    ``scenario`` (the Scenario), ``crash_pos`` (N, 3, NaN if none), ``covered`` at the end,
    ``method`` (the name, or the factory's ``__name__``) and ``log``: the episode's
    :class:`~masp_lite.evaluation.metrics.EpisodeLog` at every step (SR, Steps and CR as evaluated).
    """
    import torch

    from ..envs import make
    from ..envs.drone_model import CONTROL_DT
    from ..evaluation.metrics import EpisodeLog
    from ..policies import make_policy

    if not isinstance(stride, int) or stride < 1:
        raise ValueError(f"stride: expected a positive int, got {stride!r}")
    world = make(scenario, num_envs=1, seed=seed, **overrides)
    if world.scenario.kind != "drone":
        raise ValueError(f"scenario {world.scenario.name!r}: expected a drone scenario for 3-D playback")
    policy = make_policy(method, world) if isinstance(method, str) else method(world)
    obs = world.reset(seed=seed)
    policy.reset(obs)
    frames = [obs]
    crashed = np.zeros(world.num_agents, bool)
    every = {k: [obs[k][0].clone()] for k in ("covered", "reached", "alive")}  # each step, for the metrics
    contacts = []
    for t in range(world.horizon):
        obs, info = world.step(policy.act(obs))
        crashed |= (info["agent_collisions"][0] > 0).numpy()
        for k in every:
            every[k].append(obs[k][0].clone())
        contacts.append(info["collisions"][0])
        if (t + 1) % stride == 0 or t + 1 == world.horizon:
            frames.append(obs)
    log = EpisodeLog(*(torch.stack(every[k])[None] for k in ("covered", "reached")),
                     torch.stack(contacts).long()[None], torch.stack(every["alive"])[None],
                     varying=bool(world.scenario.varying), horizon=int(world.horizon))
    pick = lambda k: np.stack([f[k][0].detach().cpu().numpy() for f in frames])  # noqa: E731
    pos, alive = pick("agent_pos").astype(np.float64), pick("alive")
    crash_pos = np.where(crashed[:, None], pos[-1], np.nan)
    return {"pos": pos, "quat": pick("agent_quat").astype(np.float64), "alive": alive,
            "reached": pick("reached"), "covered": frames[-1]["covered"][0].numpy(), "crashed": crashed,
            "landmark_pos": frames[0]["landmark_pos"][0].numpy().astype(np.float64), "crash_pos": crash_pos,
            "dt": CONTROL_DT * stride, "scenario": world.scenario, "log": log,
            "method": method if isinstance(method, str) else getattr(method, "__name__", type(method).__name__)}


def _pose(p, q=None) -> np.ndarray:
    m = np.eye(4)
    if q is not None:
        import meshcat.transformations as tf
        m = tf.quaternion_matrix(q)  # meshcat's transformations take (w, x, y, z), as MuJoCo
    m[:3, 3] = p
    return m


def build_scene(vis, episode: dict) -> None:
    """Draw ``episode`` (from :func:`record_episode`) into a meshcat ``Visualizer`` and animate it."""
    mc = _meshcat()
    g = mc.geometry
    from ..envs.drone_model import ARM_LENGTH, HUMMINGBIRD, ROTOR_RADIUS, rotor_positions

    sc, pos, quat = episode["scenario"], episode["pos"], episode["quat"]
    T, N = pos.shape[:2]
    colours = [int(255 * r) << 16 | int(255 * gg) << 8 | int(255 * b) for r, gg, b in _palette(N)]
    vis.delete()
    ws = sc.world_size
    mark = marker_radius(sc)
    # camera behind the map's -y edge, looking at the centre; the "rotated" frame is y-up
    vis["/Cameras/default"].set_transform(np.eye(4))
    vis["/Cameras/default/rotated/<object>"].set_property("position", [0.0, 0.45 * ws, 0.6 * ws])
    vis["/Axes"].set_property("visible", False)
    vis["floor"].set_object(g.Box([ws, ws, 0.01]), g.MeshLambertMaterial(color=0xdddddd))
    vis["floor"].set_transform(_pose([0, 0, -0.005]))
    rot_x = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1.0]])  # meshcat cylinders lie on y
    for i in range(N):
        d = vis["drones"][str(i)]
        d["hub"].set_object(g.Box([0.1, 0.1, 0.05]), g.MeshLambertMaterial(color=colours[i]))
        for k, ((x, y), s) in enumerate(zip(rotor_positions(), HUMMINGBIRD["directions"])):
            arm = d["arm"][str(k)]
            arm.set_object(g.Box([ARM_LENGTH, 0.02, 0.01]), g.MeshLambertMaterial(color=0x444444))
            arm.set_transform(_pose([x / 2, y / 2, 0], _yaw_quat(np.arctan2(y, x))))
            rotor = d["rotor"][str(k)]
            rotor.set_object(g.Cylinder(0.008, ROTOR_RADIUS),
                             g.MeshLambertMaterial(color=SPIN_MINUS if s < 0 else SPIN_PLUS, opacity=0.7,
                                                   transparent=True))
            rotor.set_transform(_pose([x, y, 0.02]) @ rot_x)
        path = pos[:, i][episode["alive"][:, i] | _first_gone(episode["alive"][:, i])]
        vis["trails"][str(i)].set_object(g.Line(g.PointsGeometry(path.T.astype(np.float32)),
                                                g.LineBasicMaterial(color=colours[i])))
        lm = vis["landmarks"][str(i)]
        lm["ball"].set_object(g.Sphere(sc.landmark_radius), g.MeshLambertMaterial(color=LANDMARK))
        lm["marker"].set_object(g.Sphere(mark), g.MeshLambertMaterial(color=LANDMARK, opacity=0.35, transparent=True))
        height = float(episode["landmark_pos"][i][2])
        if height > 0:  # a stem from the floor: the landmark's height reads from any angle
            lm["stem"].set_object(g.Cylinder(height, 0.012), g.MeshLambertMaterial(color=LANDMARK, opacity=0.5,
                                                                                   transparent=True))
            lm["stem"].set_transform(_pose([0, 0, -height / 2]) @ rot_x)
        lm["halo"].set_object(g.Sphere(1.6 * mark), g.MeshLambertMaterial(color=REACHED, opacity=0.45,
                                                                          transparent=True))
        lm.set_transform(_pose(episode["landmark_pos"][i]))
        vis["crashes"][str(i)].set_object(g.Sphere(0.3), g.MeshLambertMaterial(color=CRASH, opacity=0.6,
                                                                             transparent=True))
        vis["crashes"][str(i)].set_transform(_pose(np.nan_to_num(episode["crash_pos"][i], nan=0.0)))
    fps = 1.0 / episode["dt"]
    anim = mc.animation.Animation(default_framerate=fps)
    tiny, one, big = [1e-4] * 3, [1.0] * 3, [drone_scale(sc)] * 3
    for f in range(T):
        with anim.at_frame(vis, f) as frame:
            for i in range(N):
                alive = bool(episode["alive"][f, i])
                drone = frame["drones"][str(i)]
                drone.set_transform(_pose(pos[f, i], quat[f, i]))
                drone.set_property("scale", "vector3", big if alive else tiny)
                frame["landmarks"][str(i)]["halo"].set_property(
                    "scale", "vector3", one if episode["reached"][f, i] else tiny)
                gone = episode["crashed"][i] and not alive
                frame["crashes"][str(i)].set_property("scale", "vector3", one if gone else tiny)
    vis.set_animation(anim, play=True, repetitions=1)


def _first_gone(alive: np.ndarray) -> np.ndarray:
    """The first frame after a drone left, so that its trail ends where it left."""
    out = np.zeros_like(alive)
    idx = np.flatnonzero(~alive)
    if len(idx):
        out[idx[0]] = True
    return out


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)])


def _palette(n: int) -> np.ndarray:
    import matplotlib
    return np.asarray(matplotlib.colormaps["tab20"](np.arange(n) % 20))[:, :3]


class RecordingWindow:
    """A stand-in for meshcat's ``ViewerWindow`` that stores the commands instead of sending them."""

    def __init__(self):
        self.commands: list[bytes] = []

    def send(self, command) -> None:
        import umsgpack
        self.commands.append(umsgpack.packb(command.lower()))

    def static_html(self, overlay: str = "", title: str = "masp-lite drones") -> str:
        """meshcat's static page: its viewer script, then every command as a base64 blob.

        ``overlay`` is HTML shown over the scene's top-left corner (the key); meshcat's own
        controls stay at the top right. ``title`` is the page's title.
        """
        mc = _meshcat()
        root = os.path.join(os.path.dirname(mc.__file__), "viewer", "dist", "main.min.js")
        with open(root, encoding="utf-8") as f:
            viewer_js = f.read()
        commands = "var sent = [];\n" + "".join(
            'sent.push(fetch("data:application/octet-binary;base64,{}").then(r => r.arrayBuffer())'
            ".then(b => viewer.handle_command_bytearray(new Uint8Array(b))));\n".format(
                base64.b64encode(c).decode("ascii")) for c in self.commands)
        # meshcat's controls list the Scene tree first, so in a short cell the Animations panel
        # (play / pause / speed) sat below the bottom edge: fold Scene, open Animations, and let
        # the panel scroll inside the page
        controls = ("Promise.all(sent).then(function () { var g = viewer.gui, f = g && g.__folders;"
                    " if (f && f.Scene) f.Scene.close(); if (f && f.Animations) f.Animations.open(); });\n")
        return (f"<!DOCTYPE html>\n<html><head><meta charset=utf-8><title>{html_lib.escape(title)}</title>"
                "<style>body{margin:0}#meshcat-pane{width:100vw;height:100vh;overflow:hidden}"
                ".dg.main>ul{max-height:calc(100vh - 20px);overflow-y:auto}"
                "#masp-key{position:absolute;top:8px;left:8px;z-index:10;background:rgba(255,255,255,.85);"
                "font:12px/1.45 sans-serif;padding:6px 9px;border-radius:4px;pointer-events:none}"
                "#masp-key i{display:inline-block;width:10px;height:10px;border-radius:50%;margin-right:5px}"
                "</style></head>"
                f"<body><div id=\"meshcat-pane\"></div>{overlay}<script>{viewer_js}</script><script>"
                "var viewer = new MeshCat.Viewer(document.getElementById('meshcat-pane'));\n"
                f"{commands}{controls}</script></body></html>")


def _key(episode: dict, floating: bool = True) -> str:
    """The key of a recorded episode: method, scenario, outcome, and what each colour means.

    ``floating``: over the scene's top-left corner (the standalone page); otherwise a plain
    block to put under the view (the playground, whose panes are too narrow for an overlay).
    """
    sc, esc = episode["scenario"], html_lib.escape
    swatch = lambda colour, text: f'<i style="background:#{colour:06x}"></i>{text}<br>'  # noqa: E731
    covered = f"{int(np.sum(episode['covered']))}/{len(episode['covered'])} landmarks covered at the end"
    opening = ('<div id="masp-key">' if floating else
               '<div class="masp-key" style="font:12px/1.45 sans-serif">'
               '<style>.masp-key i{display:inline-block;width:10px;height:10px;border-radius:50%;'
               'margin-right:5px}</style>')
    return (f'{opening}<b>{esc(str(episode.get("method", "")))}</b> on {esc(sc.name)}: {covered}<br>'
            + swatch(LANDMARK, "landmark (translucent marker, stem to the floor)")
            + swatch(REACHED, "halo: landmark reached")
            + swatch(CRASH, "crash")
            + swatch(SPIN_MINUS, "rotor spinning −1")
            + swatch(SPIN_PLUS, "rotor spinning +1")
            + "hub and trail: one colour per drone<br>"
            + (f"drones drawn {drone_scale(sc):g}× their size<br>" if drone_scale(sc) > 1 else "")
            + "drag to rotate, scroll to zoom; replay: Open Controls → Animations → play</div>")


def key_html(episode: dict) -> str:
    """The episode's key as a plain HTML block, to show beside or under a view without its overlay."""
    return _key(episode, floating=False)


def episode_html(episode: dict, key: bool = True) -> str:
    """The standalone page (str) of a recorded episode, with its on-screen key unless ``key=False``."""
    mc = _meshcat()
    window = RecordingWindow()
    build_scene(mc.Visualizer(window=window), episode)
    title = f"masp-lite: {episode.get('method', '')} on {episode['scenario'].name}"
    return window.static_html(overlay=_key(episode) if key else "", title=title)


def play_to_html(method, scenario, out, seed: int = 0, **overrides) -> str:
    """Record one episode of ``method`` on ``scenario`` and write it as a standalone page ``out``."""
    page = episode_html(record_episode(method, scenario, seed=seed, **overrides))
    atomic_write(out, page)
    return str(out)


def notebook_html(episode_or_page, height: int = 480):
    """An ``IPython.display.HTML`` iframe showing the standalone page in a notebook cell."""
    from IPython.display import HTML
    page = episode_or_page if isinstance(episode_or_page, str) else episode_html(episode_or_page)
    return HTML(f'<div><iframe srcdoc="{html_lib.escape(page, quote=True)}" '
                f'style="width:100%;height:{int(height)}px;border:none"></iframe></div>')


class LiveViewer:
    """meshcat's server on 127.0.0.1 for live playback; stopped on ``close()`` or leaving ``with``."""

    def __init__(self):
        mc = _meshcat()
        from meshcat.servers.zmqserver import start_zmq_server_as_subprocess
        self._proc, zmq_url, self.web_url = start_zmq_server_as_subprocess(server_args=[])
        if "127.0.0.1" not in self.web_url:
            self.close()
            raise RuntimeError(f"meshcat server not bound to 127.0.0.1: {self.web_url}")
        self.vis = mc.Visualizer(zmq_url=zmq_url)

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    def show(self, episode: dict) -> None:
        """Draw and animate a recorded episode in the live viewer."""
        build_scene(self.vis, episode)

    def cell(self, height: int = 480):
        """The viewer as a notebook output: an iframe on the local server, blank once it stops.

        For a notebook that is saved and reopened, show :func:`notebook_html` instead.
        """
        return self.vis.jupyter_cell(height=height)

    def close(self) -> None:
        vis = getattr(self, "vis", None)
        if vis is not None:
            vis.window.zmq_socket.close(linger=0)
            self.vis = None
        if getattr(self, "_proc", None) is not None:
            self._proc.kill()
            self._proc.wait()
            self._proc = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        self.close()
