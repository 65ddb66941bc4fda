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
order to match the MPE paper's dynamics, and so does this world. The scenario override
``integration="velocity_first"`` restores the original order, for experiments only.

Bodies are circles: agents (``agent_radius``), immovable obstacles that collide with
agents, and landmarks that collide with nothing. When the team shrinks (``team_after``),
the dropped agents leave the world right after step ``change_step``: they stop moving,
stop colliding and stop covering landmarks; ``alive`` says who is in.

Observations are a dict of tensors (see :meth:`ParticleWorld.observe`); ``step`` also
returns per-episode counters (covered landmarks, collision events, alive mask) that the
metrics in :mod:`masp_lite.eval` consume.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from .scenarios import Scenario, get_scenario

__all__ = ["ParticleWorld", "make", "PHYSICS", "ACTION_DIRECTIONS", "NUM_ACTIONS"]

#: MPE's physical constants (``mpe2``'s ``World`` and ``Entity`` defaults).
PHYSICS = dict(dt=0.1, damping=0.25, mass=1.0, contact_force=1e2, contact_margin=1e-3,
               sensitivity=5.0)

#: Unit force direction of each discrete action id, as in PettingZoo's MPE.
ACTION_DIRECTIONS = ((0.0, 0.0), (-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0))
NUM_ACTIONS = len(ACTION_DIRECTIONS)

_SPAWN_GAP = 0.01  # bodies start at least this far apart, so nothing is in contact at t = 0


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


class ParticleWorld:
    """``num_envs`` independent MPE navigation episodes stepped together.

    State tensors (``B = num_envs``, ``N`` agents = landmarks, ``K`` obstacles):
    ``agent_pos``/``agent_vel`` (B, N, 2), ``landmark_pos`` (B, N, 2),
    ``obstacle_pos`` (B, K, 2), ``alive`` (B, N) bool, ``reached`` (B, N) bool
    (landmark ever reached this episode), ``t`` (B,) steps taken.
    """

    def __init__(self, scenario: str | Scenario = "mpe-5", num_envs: int = 1,
                 device: str | torch.device = "cpu", seed: int | None = None,
                 dtype: torch.dtype = torch.float32, **overrides):
        self.scenario = get_scenario(scenario, **overrides)
        if self.scenario.kind != "particle":
            raise ValueError(f"scenario {self.scenario.name!r} is a {self.scenario.kind} scenario; "
                             "expected a particle scenario (mpe-*)")
        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f"num_envs: expected a positive int, got {num_envs!r}")
        if dtype not in (torch.float32, torch.float64):
            raise ValueError(f"dtype: expected torch.float32 or torch.float64, got {dtype}")
        self.num_envs = int(num_envs)
        try:
            self.device = torch.device(device)
        except (RuntimeError, TypeError) as e:
            raise ValueError(f"device: expected a torch device such as 'cpu' or 'cuda', got {device!r}") from e
        self.dtype = dtype
        sc = self.scenario
        self.num_agents = sc.num_agents
        self.num_landmarks = sc.num_landmarks
        self.num_obstacles = sc.num_obstacles
        self.horizon = sc.horizon
        self._rng = torch.Generator()  # spawns are drawn on the CPU: same numbers on every device
        if seed is None:
            self._rng.seed()  # fresh entropy, leaving torch's global generator alone
        else:
            self._rng.manual_seed(int(seed))
        self._dirs = torch.tensor(ACTION_DIRECTIONS, dtype=dtype, device=self.device) * PHYSICS["sensitivity"]
        eye = torch.eye(self.num_agents, dtype=torch.bool, device=self.device)
        self._not_self = ~eye
        self._upper = torch.triu(torch.ones_like(eye), diagonal=1)
        self.reset()

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict | None = None,
              env_ids: torch.Tensor | list[int] | None = None) -> dict[str, torch.Tensor]:
        """Start new episodes (all, or only ``env_ids``) and return the observation.

        ``options`` may give the start state: ``agent_pos`` (N, 2), ``landmark_pos`` (N, 2),
        ``obstacle_pos`` (K, 2), ``agent_vel`` (N, 2) — or with a leading batch dimension
        matching the episodes being reset — and ``keep`` (N,) bool, the agents that stay
        after a team-size change. Anything not given is drawn at random.
        """
        if seed is not None:
            self._rng.manual_seed(int(seed))
        sc, B, N, K = self.scenario, self.num_envs, self.num_agents, self.num_obstacles
        ids = self._env_ids(env_ids)
        n = len(ids)
        options = dict(options or {})
        unknown = sorted(set(options) - {"agent_pos", "landmark_pos", "obstacle_pos", "agent_vel", "keep"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; expected agent_pos, landmark_pos, "
                             "obstacle_pos, agent_vel, keep")
        given = {k: self._option(options[k], k, n, shape) for k, shape in
                 (("obstacle_pos", (K, 2)), ("agent_pos", (N, 2)), ("landmark_pos", (N, 2)),
                  ("agent_vel", (N, 2))) if k in options}
        obst, agents, lms = self._spawn(n, given)
        keep = self._team_after_mask(n, options.get("keep"))
        self._check_no_overlap(agents, obst, lms)

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

    def _env_ids(self, env_ids):
        if env_ids is None:
            return torch.arange(self.num_envs)
        ids = torch.as_tensor(env_ids, dtype=torch.long).reshape(-1).cpu()
        if len(ids) and (ids.min() < 0 or ids.max() >= self.num_envs):
            raise ValueError(f"env_ids: expected indices in [0, {self.num_envs}), got {ids.tolist()}")
        return ids

    def _option(self, value, name, n, shape):
        t = torch.as_tensor(np.asarray(value, dtype=np.float64) if not torch.is_tensor(value) else value,
                            dtype=torch.float64).cpu()
        if t.shape == shape:
            t = t.expand(n, *shape)
        if t.shape != (n, *shape):
            raise ValueError(f"reset option {name!r}: expected shape {shape} or {(n, *shape)}, "
                             f"got {tuple(t.shape)}")
        if not torch.isfinite(t).all():
            raise ValueError(f"reset option {name!r}: expected finite values")
        return t.clone()

    def _team_after_mask(self, n, keep):
        sc, N = self.scenario, self.num_agents
        if keep is not None:
            k = torch.as_tensor(np.asarray(keep)).cpu()
            if k.dtype != torch.bool or k.shape not in ((N,), (n, N)):
                raise ValueError(f"reset option 'keep': expected a bool array of shape ({N},), "
                                 f"got {tuple(k.shape)} {k.dtype}")
            return k.expand(n, N).clone()
        if not sc.varying:
            return torch.ones(n, N, dtype=torch.bool)
        order = torch.rand(n, N, generator=self._rng).argsort(dim=1)
        keep = torch.zeros(n, N, dtype=torch.bool)
        keep.scatter_(1, order[:, : sc.team_after], True)
        return keep

    def _spawn(self, n, given):
        """Rejection-sample non-overlapping bodies, vectorized over episodes.

        Obstacles first, then agents (clear of obstacles and each other), then landmarks
        (clear of obstacles and each other; a landmark may lie under an agent).
        """
        sc = self.scenario
        ra, rl, ro = sc.agent_radius, sc.landmark_radius, sc.obstacle_radius
        obst = given.get("obstacle_pos") if "obstacle_pos" in given else \
            self._sample(n, self.num_obstacles, ro, [])
        agents = given.get("agent_pos") if "agent_pos" in given else \
            self._sample(n, self.num_agents, ra, [(obst, ro)])
        lms = given.get("landmark_pos") if "landmark_pos" in given else \
            self._sample(n, self.num_agents, rl, [(obst, ro)])
        return obst, agents, lms

    def _sample(self, n, count, radius, others, max_tries=10_000):
        half = self.scenario.world_size / 2 - radius
        out = torch.zeros(n, count, 2, dtype=torch.float64)
        for i in range(count):
            todo = torch.arange(n)
            for _ in range(max_tries):
                cand = (torch.rand(len(todo), 2, generator=self._rng, dtype=torch.float64) * 2 - 1) * half
                ok = torch.ones(len(todo), dtype=torch.bool)
                for pos, r in [*others, (out[:, :i], radius)]:
                    if pos.shape[1]:
                        d = (pos[todo] - cand[:, None]).norm(dim=-1)
                        ok &= (d >= r + radius + _SPAWN_GAP).all(dim=1)
                out[todo[ok], i] = cand[ok]
                todo = todo[~ok]
                if len(todo) == 0:
                    break
            else:
                raise ValueError(f"could not place {count} bodies of radius {radius} without overlap "
                                 f"in a {self.scenario.world_size:g} m map; expected a larger world_size")
        return out

    def _check_no_overlap(self, agents, obst, lms):
        sc = self.scenario

        def overlaps(a, b, dmin, same):
            d = (a[:, :, None] - b[:, None]).norm(dim=-1)
            if same:
                d = d + torch.eye(a.shape[1], dtype=d.dtype) * 1e9
            return bool((d < dmin).any()) if d.numel() else False

        if overlaps(agents, agents, 2 * sc.agent_radius, True):
            raise ValueError("reset options: agents overlap; expected agent centres at least "
                             f"{2 * sc.agent_radius:g} m apart")
        if overlaps(agents, obst, sc.agent_radius + sc.obstacle_radius, False):
            raise ValueError("reset options: an agent overlaps an obstacle; expected centres at least "
                             f"{sc.agent_radius + sc.obstacle_radius:g} m apart")
        if overlaps(obst, obst, 2 * sc.obstacle_radius, True):
            raise ValueError("reset options: obstacles overlap; expected centres at least "
                             f"{2 * sc.obstacle_radius:g} m apart")
        if overlaps(lms, obst, sc.landmark_radius + sc.obstacle_radius, False):
            raise ValueError("reset options: a landmark lies inside an obstacle; expected centres at least "
                             f"{sc.landmark_radius + sc.obstacle_radius:g} m apart")

    # ------------------------------------------------------------------- step
    def step(self, actions) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
        """Advance every episode by one step.

        ``actions``: integer tensor (B, N) of action ids in [0, 5). Dropped agents' actions
        are ignored. Returns ``(obs, info)``; ``info`` holds per-episode ``covered`` (B, N)
        landmarks covered now, ``reached`` (B, N) ever reached, ``collisions`` (B,) contact
        pairs (agent–agent + agent–obstacle) after the step, ``agent_collisions`` (B, N)
        contacts per agent, ``alive`` (B, N) and ``done`` (B,).
        """
        a = self._check_actions(actions)
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

    def _check_actions(self, actions):
        B, N = self.num_envs, self.num_agents
        if isinstance(actions, np.ndarray):
            if not np.issubdtype(actions.dtype, np.integer):
                raise ValueError(f"actions: expected an integer array, got dtype {actions.dtype}")
            actions = torch.from_numpy(actions)
        if not torch.is_tensor(actions):
            raise ValueError(f"actions: expected an integer tensor of shape ({B}, {N}), got {type(actions).__name__}")
        if actions.dtype.is_floating_point or actions.dtype.is_complex or actions.dtype == torch.bool:
            raise ValueError(f"actions: expected an integer tensor, got dtype {actions.dtype}")
        if tuple(actions.shape) != (B, N):
            raise ValueError(f"actions: expected shape (num_envs, num_agents) = ({B}, {N}), "
                             f"got {tuple(actions.shape)}")
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

    def __repr__(self):
        sc = self.scenario
        return (f"ParticleWorld({sc.name!r}, num_envs={self.num_envs}, num_agents={sc.num_agents}, "
                f"num_obstacles={sc.num_obstacles}, world_size={sc.world_size:g}, horizon={sc.horizon}, "
                f"device={str(self.device)!r})")


def make(scenario: str | Scenario, num_envs: int = 1, device: str | torch.device = "cpu",
         seed: int | None = None, **overrides):
    """Batched world for ``scenario`` (particle or drone presets; see :mod:`.scenarios`)."""
    sc = get_scenario(scenario, **overrides)
    if sc.kind == "drone":
        from .drones import DroneWorld  # imported lazily: MuJoCo is only needed for drones
        return DroneWorld(sc, num_envs=num_envs, device=device, seed=seed)
    return ParticleWorld(sc, num_envs=num_envs, device=device, seed=seed)
