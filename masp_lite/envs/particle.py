"""The batched particle world: MPE's physics over ``num_envs`` episodes at once.

Why hand-written: PettingZoo's ``mpe2`` steps one episode with Python loops over entity
pairs (~1k agent-steps/s at N=50); VMAS is batched but its physics differs from MPE's.
This module keeps ``mpe2``'s physics exactly, as batch-first torch tensors.

Physics per step (``mpe2``'s ``World.step`` today; see the course, chapter 01):

1. action force ``u = sensitivity * e(a)`` with ``e`` the unit direction of discrete
   action ``a`` (0 no-op, 1 −x, 2 +x, 3 −y, 4 +y) and ``sensitivity = 5``;
2. soft contact force between every colliding pair, from positions *before* the update:
   ``p = k * log(1 + exp(-(d - d_min) / k))``, ``f = contact_force * p * delta / d``,
   applied +/− (an immovable obstacle receives none);
3. ``pos += vel * dt`` (previous velocity), then ``vel = vel * (1 - damping)``, then
   ``vel += force / mass * dt``.

The original OpenAI MPE updated the velocity before the position; ``mpe2`` changed the
order. Every ``mpe-*`` preset uses the original order (``integration="velocity_first"``, the
world of the code the paper's descends from, :data:`~masp_lite.envs.scenarios.PAPER_WORLD`);
``integration="mpe2"`` moves exactly as PettingZoo's mpe2 (tested against it).

Bodies are circles: agents (``agent_radius``), immovable obstacles that collide with
agents, and landmarks that collide with nothing. When the team shrinks (``team_after``),
the dropped agents leave the world right after step ``change_step``: they stop moving,
stop colliding and stop covering landmarks; ``alive`` says who is in.

Observations are a dict of tensors (see :meth:`ParticleWorld.observe`); ``step`` also
returns per-episode counters (covered landmarks, collision events, alive mask) that the
metrics in :mod:`masp_lite.evaluation` consume.
"""
from __future__ import annotations

import numpy as np
import torch

from .base import BatchedWorld
from .scenarios import Scenario

__all__ = ["ParticleWorld", "PHYSICS", "ACTION_DIRECTIONS", "NUM_ACTIONS", "contact_force"]

#: MPE's physical constants (``mpe2``'s ``World`` and ``Entity`` defaults).
PHYSICS = dict(dt=0.1, damping=0.25, mass=1.0, contact_force=1e2, contact_margin=1e-3,
               sensitivity=5.0)

#: Unit force direction of each discrete action id, as in PettingZoo's MPE.
ACTION_DIRECTIONS = ((0.0, 0.0), (-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0))
NUM_ACTIONS = len(ACTION_DIRECTIONS)

_STATE = ("obstacle_pos", "agent_pos", "landmark_pos", "agent_vel", "alive", "t", "reached", "keep")
_SPAWN_GAP = 0.01  # bodies start at least this far apart, so nothing is in contact at t = 0
CENTRAL = 0.8
"""Landmarks of ``landmark_spawn="central"`` lie in the central ``CENTRAL``× square (MAGE-X's navigation)."""


def contact_force(delta: torch.Tensor, dist: torch.Tensor, dist_min: float,
                  contact_force: float = PHYSICS["contact_force"],
                  margin: float = PHYSICS["contact_margin"]) -> torch.Tensor:
    """MPE's soft contact force on body ``a`` from body ``b``; ``delta = pos_a - pos_b``.

    ``penetration = margin * log(1 + exp(-(dist - dist_min) / margin))`` is a smooth
    version of ``max(0, dist_min - dist)``; the force pushes along ``delta / dist``.
    ``delta``: (..., 2); ``dist``: (...) — returns (..., 2).
    """
    penetration = torch.nn.functional.softplus(-(dist - dist_min) / margin, threshold=30.0) * margin
    return delta * (contact_force * penetration / dist).unsqueeze(-1)


class ParticleWorld(BatchedWorld):
    """``num_envs`` independent MPE navigation episodes stepped together.

    State tensors (``B = num_envs``, ``N`` agents = landmarks, ``K`` obstacles):
    ``agent_pos``/``agent_vel`` (B, N, 2), ``landmark_pos`` (B, N, 2),
    ``obstacle_pos`` (B, K, 2), ``alive`` (B, N) bool, ``reached`` (B, N) bool
    (landmark ever reached this episode), ``t`` (B,) steps taken.
    """

    kind = "particle"
    reset_options = {"obstacle_pos": 2, "agent_pos": 2, "landmark_pos": 2, "agent_vel": 2}

    def __init__(self, scenario: str | Scenario = "mpe-5", num_envs: int = 1,
                 device: str | torch.device = "cpu", seed: int | None = None,
                 dtype: torch.dtype = torch.float32, **overrides):
        self._setup(scenario, num_envs, device, dtype, overrides)
        self._rng = torch.Generator()  # spawns are drawn on the CPU: same numbers on every device
        if seed is None:
            self._rng.seed()  # fresh entropy, leaving torch's global generator alone
        else:
            from .checks import check_seed  # loaded when first used, as the start-state checks are
            self._rng.manual_seed(check_seed(seed))
        self._dirs = torch.tensor(ACTION_DIRECTIONS, dtype=dtype, device=self.device) * PHYSICS["sensitivity"]
        eye = torch.eye(self.num_agents, dtype=torch.bool, device=self.device)
        self._not_self = ~eye
        self._upper = torch.triu(torch.ones_like(eye), diagonal=1)
        self.reset()

    def _option_bounds(self, name):
        """Positions within one map width of the centre (the map itself spans half that either
        way); velocities below ten map widths per second."""
        ws = self.scenario.world_size
        w = 10 * ws if name == "agent_vel" else ws
        return np.array(-w), np.array(w)

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict | None = None,
              env_ids: torch.Tensor | list[int] | None = None) -> dict[str, torch.Tensor]:
        """Start new episodes (all, or only ``env_ids``) and return the observation.

        ``options`` may give the start state: ``agent_pos`` (N, 2), ``landmark_pos`` (N, 2),
        ``obstacle_pos`` (K, 2), ``agent_vel`` (N, 2) — or with a leading batch dimension
        matching the episodes being reset — and ``keep`` (N,) bool, the agents that stay
        after a team-size change. Anything not given is drawn at random, apart from every
        other body; given agents may overlap one another or an obstacle, as in MPE, and
        contact then pushes them apart (:func:`~masp_lite.envs.start.check_particle_start`
        says what is refused).
        """
        if seed is not None:
            from .checks import check_seed
            self._rng.manual_seed(check_seed(seed))
        B, N, K = self.num_envs, self.num_agents, self.num_obstacles
        ids = torch.from_numpy(self._env_ids(env_ids))
        n = len(ids)
        if options is not None:
            from .checks import reset_options
            options = reset_options(options)
        options = options or {}
        given = {k: torch.from_numpy(v) for k, v in self._start_state(options, n).items()}
        obst, agents, lms = self._spawn(n, given)
        keep = torch.from_numpy(self._team_mask(n, options.get("keep")))
        if given:  # drawn bodies are apart by construction (:meth:`_spawn`); a given start is checked
            from .start import check_particle_start
            check_particle_start(self.scenario, agents, obst, lms)

        def put(name, value, shape):
            full = getattr(self, name, None)
            if full is None or full.shape != (B, *shape):
                full = torch.zeros((B, *shape), dtype=value.dtype, device=self.device)
            full = full.clone()
            full[ids] = value.to(self.device)
            setattr(self, name, full)

        cast = lambda x: x.to(self.dtype)  # noqa: E731
        put("obstacle_pos", cast(obst), (K, 2))
        put("agent_pos", cast(agents), (N, 2))
        put("landmark_pos", cast(lms), (N, 2))
        vel = given.get("agent_vel", torch.zeros(n, N, 2, dtype=torch.float64))
        put("agent_vel", cast(vel), (N, 2))
        put("alive", torch.ones(n, N, dtype=torch.bool), (N,))
        put("_keep", keep, (N,))
        put("t", torch.zeros(n, dtype=torch.long), ())
        put("reached", torch.zeros(n, N, dtype=torch.bool), (N,))
        self._geometry()
        self.reached = self.reached | self.covered
        return self.observe()

    def _random_order(self, n):
        return torch.rand(n, self.num_agents, generator=self._rng).argsort(dim=1).numpy()

    def _spawn(self, n, given):
        """The bodies of ``given``, the rest rejection-sampled without overlap, vectorized over episodes.

        Obstacles first (clear of given agents and landmarks), then agents (clear of
        obstacles and each other), then landmarks (clear of obstacles and each other; a
        landmark may lie under an agent). Obstacles and agents are uniform over the map;
        landmarks too, or over the central 0.8× square (``Scenario.landmark_spawn``). The
        paper does not say where its obstacles go. Only what is drawn here is kept apart:
        given agents may overlap (see :func:`~masp_lite.envs.start.check_particle_start`).
        """
        sc = self.scenario
        ra, rl, ro = sc.agent_radius, sc.landmark_radius, sc.obstacle_radius
        placed = [(given[k], r) for k, r in (("agent_pos", ra), ("landmark_pos", rl)) if k in given]
        obst = given.get("obstacle_pos") if "obstacle_pos" in given else \
            self._sample(n, self.num_obstacles, ro, placed)
        agents = given.get("agent_pos") if "agent_pos" in given else \
            self._sample(n, self.num_agents, ra, [(obst, ro)])
        lms = given.get("landmark_pos") if "landmark_pos" in given else \
            self._sample(n, self.num_agents, rl, [(obst, ro)], central=sc.landmark_spawn == "central")
        return obst, agents, lms

    def _sample(self, n, count, radius, others, central=False):
        """Uniform over the map, the body inside it; ``central``: MAGE-X's landmark square,
        ``0.8 * uniform(-L/2, L/2)`` on each axis."""
        L = self.scenario.world_size
        half = CENTRAL * L / 2 if central else L / 2 - radius
        out = torch.zeros(n, count, 2, dtype=torch.float64)

        def draw(m):
            return (torch.rand(m, 2, generator=self._rng, dtype=torch.float64) * 2 - 1) * half

        def clear(todo, cand, i):
            ok = torch.ones(len(todo), dtype=torch.bool)
            for pos, r in [*others, (out[:, :i], radius)]:
                if pos.shape[1]:
                    d = (pos[todo] - cand[:, None]).norm(dim=-1)
                    ok &= (d >= r + radius + _SPAWN_GAP).all(dim=1)
            return ok

        return self._place(out, draw, clear, f"{count} bodies of radius {radius} without overlap")

    # ------------------------------------------------------------------- step
    def step(self, actions) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
        """Advance every episode by one step.

        ``actions``: integer tensor (B, N) of action ids in [0, 5). Dropped agents' actions
        are ignored. Returns ``(obs, info)``; ``info`` holds per-episode ``covered`` (B, N)
        landmarks covered now, ``reached`` (B, N) ever reached, ``collisions`` (B,) contact
        pairs (agent–agent + agent–obstacle) after the step, ``agent_collisions`` (B, N)
        contacts per agent, ``alive`` (B, N) and ``done`` (B,).
        """
        a = self._actions(actions)
        if bool((self.t >= self.horizon).any()):
            raise ValueError(f"episode over (horizon {self.horizon} reached); expected reset() before step()")
        sc, p = self.scenario, PHYSICS
        alive = self.alive
        alive_f = alive.to(self.dtype).unsqueeze(-1)
        force = self._dirs[a] * alive_f                                             # action force
        pair_f = contact_force(self._aa_delta, self._aa_dist, 2 * sc.agent_radius)  # (B, N, N, 2)
        pair_mask = (alive[:, :, None] & alive[:, None, :] & self._not_self).to(self.dtype)
        force = force + (pair_f * pair_mask.unsqueeze(-1)).sum(dim=2)
        if self.num_obstacles:
            obst_f = contact_force(self._ao_delta, self._ao_dist, sc.agent_radius + sc.obstacle_radius)
            force = force + obst_f.sum(dim=2) * alive_f
        new_vel = (self.agent_vel * (1 - p["damping"]) + force / p["mass"] * p["dt"]) * alive_f
        # mpe2 moves with the old velocity; the original MPE (velocity_first) with the new one
        moving = self.agent_vel if sc.integration == "mpe2" else new_vel
        self.agent_pos = self.agent_pos + moving * p["dt"] * alive_f
        self.agent_vel = new_vel
        self.t = self.t + 1
        if sc.varying:
            changed = (self.t == sc.change_step).unsqueeze(-1)
            self.alive = torch.where(changed, self.alive & self._keep, self.alive)
            self.agent_vel = self.agent_vel * self.alive.unsqueeze(-1)  # leavers stop at once
        self._geometry()
        self.reached = self.reached | self.covered
        return self.observe(), self.info()

    def _actions(self, actions) -> torch.Tensor:
        actions = self._check_actions(actions, integer=True)
        if isinstance(actions, np.ndarray):
            actions = torch.from_numpy(actions)
        actions = actions.to(self.device, torch.long)
        if bool(((actions < 0) | (actions >= NUM_ACTIONS)).any()):
            raise ValueError(f"actions: expected ids in [0, {NUM_ACTIONS}) "
                             "(0 no-op, 1 -x, 2 +x, 3 -y, 4 +y), got values outside")
        return actions

    def _geometry(self):
        """Pairwise geometry of the current positions; reused by the next step's forces."""
        sc, pos = self.scenario, self.agent_pos
        self._aa_delta = pos.unsqueeze(2) - pos.unsqueeze(1)                      # (B, N, N, 2)
        self._aa_dist = self._aa_delta.norm(dim=-1).masked_fill(~self._not_self, 1.0)
        self._ao_delta = pos.unsqueeze(2) - self.obstacle_pos.unsqueeze(1)        # (B, N, K, 2)
        self._ao_dist = self._ao_delta.norm(dim=-1)
        alive = self.alive
        both = alive.unsqueeze(2) & alive.unsqueeze(1) & self._not_self
        aa_hit = (self._aa_dist < 2 * sc.agent_radius) & both
        ao_hit = (self._ao_dist < sc.agent_radius + sc.obstacle_radius) & alive.unsqueeze(2)
        self.agent_collisions = aa_hit.sum(2) + ao_hit.sum(2)
        self.collisions = (aa_hit & self._upper).sum((1, 2)) + ao_hit.sum((1, 2))
        al_dist = torch.cdist(pos, self.landmark_pos)                             # (B, N, L)
        self.covered = ((al_dist <= sc.reach_distance) & alive.unsqueeze(2)).any(dim=1)

    # ----------------------------------------------------------------- state
    def get_state(self) -> dict[str, torch.Tensor]:
        """Every episode's full state (copies): positions, velocities, team, time, reached.

        :meth:`set_state` takes such a state back mid-episode, as it is (contacts, velocities,
        time and team included), e.g. to branch copies of an episode for a search."""
        return {k: getattr(self, "_keep" if k == "keep" else k).clone() for k in _STATE}

    def set_state(self, state: dict, repeat: int = 1) -> dict[str, torch.Tensor]:
        """Continue from ``state`` (a :meth:`get_state` of a world of this scenario); returns the observation.

        ``repeat``: each of the state's ``num_envs / repeat`` episodes becomes the state of
        ``repeat`` consecutive episodes here (``repeat = 1``: the same episodes)."""
        if set(state) != set(_STATE):
            raise ValueError(f"set_state: expected the keys {list(_STATE)}, got {sorted(state)}")
        if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1 or self.num_envs % repeat:
            raise ValueError(f"set_state: expected repeat to divide num_envs = {self.num_envs}, got {repeat!r}")
        for k in _STATE:
            v = state[k]
            want = (self.num_envs // repeat, *getattr(self, "_keep" if k == "keep" else k).shape[1:])
            if not torch.is_tensor(v) or tuple(v.shape) != want:
                raise ValueError(f"set_state: {k!r} expected a tensor of shape {want}, got "
                                 f"{tuple(v.shape) if torch.is_tensor(v) else type(v).__name__}")
            cur = getattr(self, "_keep" if k == "keep" else k)
            setattr(self, "_keep" if k == "keep" else k, v.repeat_interleave(repeat, dim=0).to(cur.device, cur.dtype))
        self._geometry()
        return self.observe()

    # ------------------------------------------------------------- RNG state
    def get_rng_state(self) -> torch.Tensor:
        """State of the world's own generator (spawns, team changes), for exact resumes."""
        return self._rng.get_state()

    def set_rng_state(self, state: torch.Tensor) -> None:
        """Restore a state from :meth:`get_rng_state`."""
        self._rng.set_state(state)

    # ------------------------------------------------------------- observing
    @property
    def done(self) -> torch.Tensor:
        return self.t >= self.horizon

    def observe(self) -> dict[str, torch.Tensor]:
        """Everything MASP and the baselines read, batch-first (see the class docstring)."""
        return {"agent_pos": self.agent_pos, "agent_vel": self.agent_vel,
                "landmark_pos": self.landmark_pos, "obstacle_pos": self.obstacle_pos,
                "alive": self.alive, "covered": self.covered, "reached": self.reached, "t": self.t}

    def info(self) -> dict[str, torch.Tensor]:
        return {"covered": self.covered, "reached": self.reached, "collisions": self.collisions,
                "agent_collisions": self.agent_collisions, "alive": self.alive, "done": self.done,
                "t": self.t}
