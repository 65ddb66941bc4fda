"""PettingZoo face of the particle world: one episode as a ``pettingzoo.ParallelEnv``.

``masp_lite.envs.parallel_env(scenario, render_mode=None, **overrides)`` wraps a
:class:`~masp_lite.envs.particle.ParticleWorld` with ``num_envs=1`` in a
:class:`ParticleParallelEnv`; the physics, spawns and team-size change are the world's.

========================  ===============================================================
Agents                    ``agent_0`` … ``agent_{N-1}``
Actions                   ``Discrete(5)``: 0 no-op, 1 −x, 2 +x, 3 −y, 4 +y (PettingZoo MPE ids)
Observation               ``Box(-inf, inf, (7N - 1 + 2K,), float32)`` per agent, see below
Reward                    simple_spread's, see below
Termination               an agent dropped by a team-size change, at the step it leaves
Truncation                every remaining agent at step ``horizon``
State                     ``state()``: all positions, velocities, alive flags; ``(7N + 2K,)``
========================  ===============================================================

Observation of agent ``i`` (``N`` agents = landmarks, ``K`` obstacles), in this order;
positions in metres, velocities in metres per second; "relative" means
*other minus self*:

====================================  ==========  ====================================
block                                 length      notes
====================================  ==========  ====================================
own velocity                          2
own position                          2           map centre is the origin
landmark positions, relative          2 N         landmark order 0 … N-1
other agents' positions, relative     2 (N - 1)   agents j ≠ i in index order
other agents' velocities, relative    2 (N - 1)   same order
other agents' alive flags             N - 1       1.0 alive, 0.0 dropped
obstacle positions, relative          2 K         obstacle order 0 … K-1
====================================  ==========  ====================================

A dropped agent's position and velocity slots are zero and its alive flag is 0, so the
layout never changes during an episode. This is simple_spread's observation
(``[vel, pos, landmarks, other agents]``) without its communication slots, plus what
MASP's observations also need: the others' velocities, who is still in, and obstacles.

Reward: MASP trains with its own rewards (Goal Matcher and executor rewards, in the
training code); this face offers PettingZoo users mpe2's ``simple_spread`` reward with
its default ``local_ratio = 0.5``, counting obstacles as well as agents::

    r_i = 0.5 * (-sum over landmarks l of min_{alive j} |p_j - l|) + 0.5 * (-contacts_i)

where ``contacts_i`` counts the alive agents and obstacles agent ``i`` touches after the
step (``info["agent_collisions"]`` of the world).

``reset(seed=None, options=None)`` accepts the world's start-state options
``agent_pos`` (N, 2), ``landmark_pos`` (N, 2), ``obstacle_pos`` (K, 2), ``agent_vel``
(N, 2) and ``keep`` (N,) bool; the world validates shapes and overlaps. Any other key
only warns: PettingZoo's own ``parallel_api_test`` calls ``reset(options={"options": 1})``
and must pass.

Rendering (``"rgb_array"``: a uint8 image from a matplotlib Agg canvas; ``"human"``: a
matplotlib window, or the notebook output) is drawn here with a handful of matplotlib
collections: enough to watch an episode; :mod:`masp_lite.viz` makes the course's
animations.
"""
from __future__ import annotations

import gymnasium
import numpy as np
import torch

from ..particle import NUM_ACTIONS, ParticleWorld
from ..scenarios import Scenario
from .base import WorldParallelEnv

__all__ = ["ParticleParallelEnv", "LOCAL_RATIO", "RESET_OPTIONS"]

#: Weight of the agent's own contact penalty; ``1 - LOCAL_RATIO`` weighs the team's coverage term.
LOCAL_RATIO = 0.5
#: Start-state keys ``reset(options=...)`` understands.
RESET_OPTIONS = ("agent_pos", "landmark_pos", "obstacle_pos", "agent_vel", "keep")


class ParticleParallelEnv(WorldParallelEnv):
    """One particle-world episode, agent by agent (see the module docstring for the spaces)."""

    reset_options = RESET_OPTIONS

    metadata = {"name": "masp_lite_particle", "render_modes": ["human", "rgb_array"],
                "render_fps": 10, "is_parallelizable": True}

    def __init__(self, scenario: str | Scenario = "mpe-5", render_mode: str | None = None,
                 seed: int | None = None, **overrides):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: expected None or one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        self._world = ParticleWorld(scenario, num_envs=1, seed=seed, **overrides)
        self.scenario = self._world.scenario
        self.render_mode = render_mode
        N, K = self._world.num_agents, self._world.num_obstacles
        self.possible_agents = [f"agent_{i}" for i in range(N)]
        self.agents = self.possible_agents[:]
        self._index = {name: i for i, name in enumerate(self.possible_agents)}
        dim = 7 * N - 1 + 2 * K
        self.observation_spaces = {a: gymnasium.spaces.Box(-np.inf, np.inf, (dim,), np.float32)
                                   for a in self.possible_agents}
        self.action_spaces = {a: gymnasium.spaces.Discrete(NUM_ACTIONS) for a in self.possible_agents}
        self.state_space = gymnasium.spaces.Box(-np.inf, np.inf, (7 * N + 2 * K,), np.float32)
        # others[i] = the indices j != i in order: the "other agents" blocks of agent i
        self._others = np.array([[j for j in range(N) if j != i] for i in range(N)], dtype=np.int64)
        self._others = self._others.reshape(N, N - 1)
        self._fig = None

    # ---------------------------------------------------------------- spaces



    @property
    def agent_pos(self) -> np.ndarray:
        """Every agent's position (N, 2), dropped agents included (frozen where they left)."""
        return self._world.agent_pos[0].detach().cpu().numpy().copy()

    @property
    def agent_vel(self) -> np.ndarray:
        """Every agent's velocity (N, 2) (a dropped agent's is zero from the step after it leaves)."""
        return self._world.agent_vel[0].detach().cpu().numpy().copy()

    # ------------------------------------------------------------ episode
    def reset(self, seed: int | None = None, options: dict | None = None):
        self._world.reset(seed=seed, options=self._known_options(options))
        self.agents = self.possible_agents[:]
        obs = self._observe()
        infos = self._infos(self.agents)
        return {a: obs[self._index[a]] for a in self.agents}, infos

    def step(self, actions: dict):
        if not self.agents:
            raise ValueError("step: the episode is over (no agents left); expected reset() before step()")
        ids = self._check_actions(actions)
        full = torch.zeros(1, self._world.num_agents, dtype=torch.long)
        for name, a in ids.items():
            full[0, self._index[name]] = a
        _, info = self._world.step(full)
        obs, alive = self._observe(), info["alive"][0].numpy()
        rewards = self._rewards(info)
        acting = self.agents
        dropped = {a for a in acting if not alive[self._index[a]]}
        over = bool(info["done"][0])
        terminations = {a: a in dropped for a in acting}
        truncations = {a: over and a not in dropped for a in acting}
        self.agents = [] if over else [a for a in acting if a not in dropped]
        if self.render_mode == "human":
            self.render()
        return ({a: obs[self._index[a]] for a in acting}, {a: rewards[self._index[a]] for a in acting},
                terminations, truncations, self._infos(acting))

    def _check_actions(self, actions) -> dict[str, int]:
        if not isinstance(actions, dict):
            raise ValueError(f"step: expected a dict {{agent name: action id}}, got {type(actions).__name__}")
        live = set(self.agents)
        unknown = sorted(set(actions) - live, key=str)
        missing = sorted(live - set(actions), key=self._index.get)
        if unknown or missing:
            raise ValueError(f"step: expected one action for each live agent {self.agents}; "
                             f"unknown agent(s) {unknown}, missing agent(s) {missing}")
        out = {}
        for name, a in actions.items():
            value = np.asarray(a) if not torch.is_tensor(a) else a.detach().cpu().numpy()
            if value.shape != () or not np.issubdtype(value.dtype, np.integer):
                raise ValueError(f"step: action of {name!r}: expected an integer id in [0, {NUM_ACTIONS}) "
                                 f"(0 no-op, 1 -x, 2 +x, 3 -y, 4 +y), got {a!r}")
            if not 0 <= int(value) < NUM_ACTIONS:
                raise ValueError(f"step: action of {name!r}: expected an id in [0, {NUM_ACTIONS}) "
                                 f"(0 no-op, 1 -x, 2 +x, 3 -y, 4 +y), got {int(value)}")
            out[name] = int(value)
        return out

    # ---------------------------------------------------------- observing
    def state(self) -> np.ndarray:
        """Global state for centralized critics: every agent's position, velocity and alive flag,
        then landmark and obstacle positions, all absolute: ``(7N + 2K,)`` float32."""
        w = self._world
        parts = [w.agent_pos[0], w.agent_vel[0], w.alive[0, :, None], w.landmark_pos[0], w.obstacle_pos[0]]
        return np.concatenate([p.to(torch.float32).numpy().ravel() for p in parts]).astype(np.float32)

    def _observe(self) -> np.ndarray:
        """Every agent's observation as one (N, 7N - 1 + 2K) float32 array."""
        w = self._world
        pos, vel = w.agent_pos[0].numpy(), w.agent_vel[0].numpy()
        alive = w.alive[0].numpy()
        lms, obst = w.landmark_pos[0].numpy(), w.obstacle_pos[0].numpy()
        N = len(pos)
        others = self._others
        seen = alive[others][..., None]                                     # (N, N-1, 1)
        rel_pos = np.where(seen, pos[others] - pos[:, None], 0.0)
        rel_vel = np.where(seen, vel[others] - vel[:, None], 0.0)
        blocks = [vel, pos, (lms[None] - pos[:, None]).reshape(N, -1), rel_pos.reshape(N, -1),
                  rel_vel.reshape(N, -1), alive[others].astype(np.float32),
                  (obst[None] - pos[:, None]).reshape(N, -1)]
        return np.concatenate(blocks, axis=1).astype(np.float32)

    def _rewards(self, info) -> np.ndarray:
        """simple_spread's reward (module docstring), one value per agent."""
        w = self._world
        alive = w.alive[0]
        dist = torch.cdist(w.agent_pos[0].double(), w.landmark_pos[0].double())   # (N agents, N landmarks)
        nearest = dist.masked_fill(~alive[:, None], float("inf")).min(dim=0).values
        team = -float(nearest.sum())
        own = -info["agent_collisions"][0].double().numpy()
        return (1 - LOCAL_RATIO) * team + LOCAL_RATIO * own

    def _infos(self, names) -> dict[str, dict]:
        w = self._world
        contacts = w.agent_collisions[0].numpy()
        covered = int(w.covered[0].sum())
        return {a: {"collisions": int(contacts[self._index[a]]), "covered_landmarks": covered}
                for a in names}

    # ------------------------------------------------------------ drawing
    def render(self):
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' "
                                  "or 'human' to parallel_env")
            return None
        fig = self._draw()
        if self.render_mode == "rgb_array":
            fig.canvas.draw()
            return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
        import matplotlib
        import matplotlib.pyplot as plt
        backend = matplotlib.get_backend().lower()
        if "inline" in backend:
            from IPython.display import display
            display(fig, clear=True)
        elif backend not in ("agg", "pdf", "ps", "svg", "cairo", "template"):
            plt.pause(1 / self.metadata["render_fps"])
        return None

    def _draw(self):
        from matplotlib.collections import EllipseCollection
        w, sc = self._world, self.scenario
        pos, alive = w.agent_pos[0].numpy(), w.alive[0].numpy()
        lms, obst, covered = w.landmark_pos[0].numpy(), w.obstacle_pos[0].numpy(), w.covered[0].numpy()
        if self._fig is None:
            if self.render_mode == "human":
                import matplotlib.pyplot as plt
                self._fig = plt.figure(figsize=(5, 5), dpi=80)
            else:
                from matplotlib.backends.backend_agg import FigureCanvasAgg
                from matplotlib.figure import Figure
                self._fig = Figure(figsize=(5, 5), dpi=80)
                FigureCanvasAgg(self._fig)
            ax = self._ax = self._fig.add_axes((0.03, 0.02, 0.94, 0.92))
            ax.set_aspect("equal")
            ax.set_xticks([]), ax.set_yticks([])

            def circles(r, n, z):
                c = EllipseCollection(np.full(n, 2 * r), np.full(n, 2 * r), np.zeros(n), units="xy",
                                      offsets=np.zeros((n, 2)), offset_transform=ax.transData,
                                      edgecolors="k", linewidths=0.5, zorder=z)
                ax.add_collection(c)
                return c
            self._art = (circles(sc.obstacle_radius, len(obst), 1), circles(sc.landmark_radius, len(lms), 2),
                         circles(sc.agent_radius, len(pos), 3))
        art_obst, art_lms, art_agents = self._art
        art_obst.set_offsets(obst), art_obst.set_facecolor("0.2")
        art_lms.set_offsets(lms), art_lms.set_facecolor(np.where(covered[:, None], [0.2, 0.7, 0.3, 1.0],
                                                                 [0.6, 0.6, 0.6, 1.0]))
        art_agents.set_offsets(pos), art_agents.set_facecolor(np.where(alive[:, None], [0.3, 0.3, 0.85, 0.9],
                                                                       [0.8, 0.8, 0.8, 0.4]))
        half = max(sc.world_size / 2, float(np.abs(pos).max()) + sc.agent_radius) * 1.05
        self._ax.set_xlim(-half, half), self._ax.set_ylim(-half, half)
        self._ax.set_title(f"{sc.name}  t = {int(w.t[0])}/{sc.horizon}", fontsize=9)
        return self._fig

    def close(self):
        if self._fig is not None and self.render_mode == "human":
            import matplotlib.pyplot as plt
            plt.close(self._fig)
        self._fig = None
