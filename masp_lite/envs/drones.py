"""The batched quadrotor world: ``num_envs`` MuJoCo episodes of N Hummingbirds.

The paper's second testbed (section "Experiments — OmniDrones") on a CPU: N drones must
cover N landmarks (virtual balls of radius 0.05 m) in a 3-D flight volume; the action is
the throttle command of each motor; a collision is a crash. The drone and its rotor model
are described in :mod:`masp_lite.envs.drone_model`.

Interface: the same as :class:`~masp_lite.envs.particle.ParticleWorld`, in 3-D.

=====================  ===================================================================
``reset(seed, options, env_ids)``  new episodes; ``options`` may fix ``agent_pos`` (N, 3),
                       ``agent_vel`` (N, 3), ``agent_quat`` (N, 4, w x y z), ``agent_angvel``
                       (N, 3, body frame), ``landmark_pos`` (N, 3), ``keep`` (N,) bool
``step(actions)``      ``actions`` float (B, N, 4) motor commands in [−1, 1] → (obs, info)
obs                    ``agent_pos``/``agent_vel`` (B, N, 3) world frame, ``agent_quat``
                       (B, N, 4), ``agent_angvel`` (B, N, 3), ``throttle`` (B, N, 4),
                       ``landmark_pos`` (B, N, 3), ``obstacle_pos`` (B, 0, 3), ``alive``,
                       ``covered``, ``reached`` (B, N), ``t`` (B,)
info                   ``covered``, ``reached``, ``collisions`` (B,), ``agent_collisions``
                       (B, N), ``alive``, ``done``, ``t`` — the particle world's keys
=====================  ===================================================================

Choices (the paper leaves them open):

* **Flight volume.** The map is ``[-ws/2, ws/2]²`` (``ws = world_size``) from the floor
  (z = 0) to ``CEILING`` = 3 m. Drones spawn hovering at ``FLIGHT_HEIGHT`` = 1.5 m, at
  least ``2·COLLISION_RADIUS + 0.05`` m apart; landmarks anywhere with z ∈ [1, 2] m, as far
  apart from one another, so that two drones can hover on two landmarks without touching.
  Rotors start at the hover throttle.
* **Reached (3-D).** A landmark is covered when an alive drone's centre is within
  ``reach_distance = ARM_LENGTH + landmark_radius`` = 0.22 m of its centre: the ball touches
  the disc swept by the arms (the drone presets set ``agent_radius`` to the arm length,
  so ``Scenario.reach_distance`` says the same).
* **Crashes.** A drone crashes when MuJoCo reports a contact of its collision sphere with
  another drone or the floor during any physics substep of the step, or when it leaves the
  flight volume. ``collisions`` counts the events of the step: drone–drone pairs + floor
  contacts + exits, among drones alive before the step; ``agent_collisions`` the same per
  drone. A crashed drone is no longer ``alive``: it neither acts, collides nor covers
  landmarks (what it reached stays reached).
* **Leaving.** A drone that is not alive (crashed, or dropped when the team shrinks after
  ``change_step``, as in the particle world) leaves the physics: it is parked, motors off,
  at its own spot high above the map, so it touches nothing; its observed state stays the
  one it had when it left.

Batching uses ``mujoco.batch.Batch`` (one model, ``num_envs`` state rows, stepped in C, on
``threads`` threads — 1 by default); its ``rollout`` records the contact sensors after every
substep. It was picked over a Python loop of ``mj_step`` on one ``MjData`` per world, which
it matches or beats (the loop is the reference ``python -m masp_lite bench drones`` compares
against), while keeping every world's state in one array. The bookkeeping here is a fixed
cost per call, so its share of the step shrinks as worlds are batched. Internal state is
numpy (float64, MuJoCo's); observations are torch tensors on ``device``.
"""
from __future__ import annotations

import mujoco
import mujoco.batch
import numpy as np
import torch

from .drone_model import (ARM_LENGTH, COLLISION_RADIUS, HOVER_COMMAND, HUMMINGBIRD, MAX_THRUST,
                          SUBSTEPS, build_model)
from .scenarios import Scenario, get_scenario

__all__ = ["DroneWorld", "FLIGHT_HEIGHT", "CEILING", "LANDMARK_HEIGHTS"]

FLIGHT_HEIGHT = 1.5
CEILING = 3.0
LANDMARK_HEIGHTS = (1.0, 2.0)
_GAP = 0.05
_PARK_HEIGHT = 100.0
_OPTIONS = {"agent_pos": 3, "agent_vel": 3, "agent_quat": 4, "agent_angvel": 3, "landmark_pos": 3}


class DroneWorld:
    """``num_envs`` independent quadrotor navigation episodes stepped together."""

    def __init__(self, scenario: str | Scenario = "drone-5", num_envs: int = 1,
                 device: str | torch.device = "cpu", seed: int | None = None,
                 dtype: torch.dtype = torch.float32, threads: int = 1, **overrides):
        self.scenario = sc = get_scenario(scenario, **overrides)
        if sc.kind != "drone":
            raise ValueError(f"scenario {sc.name!r} is a {sc.kind} scenario; expected a drone scenario (drone-*)")
        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f"num_envs: expected a positive int, got {num_envs!r}")
        if dtype not in (torch.float32, torch.float64):
            raise ValueError(f"dtype: expected torch.float32 or torch.float64, got {dtype}")
        try:
            self.device = torch.device(device)
        except (RuntimeError, TypeError) as e:
            raise ValueError(f"device: expected a torch device such as 'cpu' or 'cuda', got {device!r}") from e
        self.dtype, self.num_envs = dtype, int(num_envs)
        self.num_agents = self.num_landmarks = sc.num_agents
        self.num_obstacles, self.horizon = 0, sc.horizon
        self.reach_distance = ARM_LENGTH + sc.landmark_radius
        half = sc.world_size / 2
        if half < COLLISION_RADIUS + _GAP:
            raise ValueError(f"world_size: expected at least {2 * (COLLISION_RADIUS + _GAP):g} m for drones")
        self._rng = np.random.default_rng(seed)
        self.model = build_model(self.num_agents)
        self.batch = mujoco.batch.Batch(self.model, self.num_envs, nthread=int(threads))
        B, N = self.num_envs, self.num_agents
        self._qpos, self._qvel, self._ctrl = (self.batch.bind(k) for k in ("qpos", "qvel", "ctrl"))
        self._park = np.zeros((N, 7))
        self._park[:, 0], self._park[:, 2], self._park[:, 3] = 3 * COLLISION_RADIUS * np.arange(N), _PARK_HEIGHT, 1
        self.throttle = np.zeros((B, N, 4))
        self._frozen = np.zeros((B, N, 13))
        self.alive = np.ones((B, N), bool)
        self._keep = np.ones((B, N), bool)
        self.t = np.zeros(B, np.int64)
        self.reached = np.zeros((B, N), bool)
        self.landmark_pos = np.zeros((B, N, 3))
        self.collisions = np.zeros(B, np.int64)
        self.agent_collisions = np.zeros((B, N), np.int64)
        self._rec = {"sensordata": np.zeros((B, SUBSTEPS, self.model.nsensordata))}
        self._q3, self._v3 = self._qpos.reshape(B, N, 7), self._qvel.reshape(B, N, 6)  # views of the state rows
        assert np.shares_memory(self._q3, self._qpos) and np.shares_memory(self._v3, self._qvel)
        self._no_obstacles = torch.zeros(B, 0, 3, dtype=dtype, device=self.device)
        self._held = {}  # name -> (array, its tensor): see _same
        self._everyone = True  # every drone of every episode is still flying
        self.reset()

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict | None = None, env_ids=None) -> dict[str, torch.Tensor]:
        """Start new episodes (all, or ``env_ids``) and return the observation (see module doc)."""
        if seed is not None:
            self._rng = np.random.default_rng(int(seed))
        N, sc = self.num_agents, self.scenario
        ids = self._env_ids(env_ids)
        n = len(ids)
        options = dict(options or {})
        unknown = sorted(set(options) - set(_OPTIONS) - {"keep"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; expected some of {sorted(_OPTIONS) + ['keep']}")
        given = {k: self._option(options[k], k, n, (N, d)) for k, d in _OPTIONS.items() if k in options}
        r = COLLISION_RADIUS + _GAP / 2
        if "agent_pos" in given:
            pos = given["agent_pos"]
        else:
            pos = self._sample(n, r, (FLIGHT_HEIGHT, FLIGHT_HEIGHT))
        lms = given["landmark_pos"] if "landmark_pos" in given else self._sample(n, r, LANDMARK_HEIGHTS)
        d = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1) + np.eye(N) * 1e9
        if (d < 2 * COLLISION_RADIUS).any():
            raise ValueError(f"reset options: drones overlap; expected centres at least {2 * COLLISION_RADIUS:g} m apart")
        quat = given.get("agent_quat", np.broadcast_to([1.0, 0, 0, 0], (n, N, 4)))
        norm = np.linalg.norm(quat, axis=-1, keepdims=True)
        if (norm < 1e-9).any():
            raise ValueError("reset option 'agent_quat': expected non-zero quaternions (w, x, y, z)")
        q = np.concatenate([pos, quat / norm], axis=-1)
        v = np.concatenate([given.get("agent_vel", np.zeros((n, N, 3))),
                            given.get("agent_angvel", np.zeros((n, N, 3)))], axis=-1)
        self.batch.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        self._qpos[ids] = q.reshape(n, -1)
        self._qvel[ids] = v.reshape(n, -1)
        self.batch.forward(ids)
        self.throttle = self.throttle.copy()
        self.throttle[ids] = np.sqrt((HOVER_COMMAND + 1) / 2)
        self._ctrl[ids] = np.square(self.throttle[ids]).reshape(n, -1) * MAX_THRUST
        self.landmark_pos = self.landmark_pos.copy()
        self.landmark_pos[ids] = lms
        self.alive = self.alive.copy()
        self.alive[ids] = True
        self._everyone = bool(self.alive.all())
        self._keep[ids] = self._team_mask(n, options.get("keep"))
        self.t, self.reached = self.t.copy(), self.reached.copy()
        self.collisions, self.agent_collisions = self.collisions.copy(), self.agent_collisions.copy()
        self.t[ids] = 0
        self.reached[ids] = False
        self.collisions[ids] = 0
        self.agent_collisions[ids] = 0
        self._update_coverage()
        return self.observe()

    def _env_ids(self, env_ids) -> np.ndarray:
        if env_ids is None:
            return np.arange(self.num_envs)
        ids = np.asarray(env_ids.cpu() if torch.is_tensor(env_ids) else env_ids, dtype=np.int64).reshape(-1)
        if len(ids) and (ids.min() < 0 or ids.max() >= self.num_envs):
            raise ValueError(f"env_ids: expected indices in [0, {self.num_envs}), got {ids.tolist()}")
        return ids

    def _option(self, value, name, n, shape) -> np.ndarray:
        a = np.asarray(value.detach().cpu() if torch.is_tensor(value) else value, dtype=np.float64)
        if a.shape == shape:
            a = np.broadcast_to(a, (n, *shape))
        if a.shape != (n, *shape):
            raise ValueError(f"reset option {name!r}: expected shape {shape} or {(n, *shape)}, got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"reset option {name!r}: expected finite values")
        return a.copy()

    def _team_mask(self, n, keep) -> np.ndarray:
        sc, N = self.scenario, self.num_agents
        if keep is not None:
            k = np.asarray(keep.cpu() if torch.is_tensor(keep) else keep)
            if k.dtype != bool or k.shape not in ((N,), (n, N)):
                raise ValueError(f"reset option 'keep': expected a bool array of shape ({N},), got {k.shape} {k.dtype}")
            return np.broadcast_to(k, (n, N))
        if not sc.varying:
            return np.ones((n, N), bool)
        order = self._rng.random((n, N)).argsort(axis=1)
        keep = np.zeros((n, N), bool)
        np.put_along_axis(keep, order[:, : sc.team_after], True, axis=1)
        return keep

    def _sample(self, n, radius, heights, max_tries=10_000) -> np.ndarray:
        """Rejection-sample N points per episode, pairwise at least ``2 * radius`` apart."""
        N, half = self.num_agents, self.scenario.world_size / 2 - COLLISION_RADIUS - _GAP
        out = np.zeros((n, N, 3))
        for i in range(N):
            todo = np.arange(n)
            for _ in range(max_tries):
                cand = np.concatenate([self._rng.uniform(-half, half, (len(todo), 2)),
                                       self._rng.uniform(*heights, (len(todo), 1))], axis=1)
                ok = (np.linalg.norm(out[todo, :i] - cand[:, None], axis=-1) >= 2 * radius).all(axis=1)
                out[todo[ok], i] = cand[ok]
                todo = todo[~ok]
                if not len(todo):
                    break
            else:
                raise ValueError(f"could not place {N} drones {2 * radius:.2f} m apart in a "
                                 f"{self.scenario.world_size:g} m map; expected a larger world_size")
        return out

    # ------------------------------------------------------------------- step
    def step(self, actions) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
        """Advance every episode by one control step (``SUBSTEPS`` MuJoCo steps)."""
        cmd = self._check_actions(actions)
        if self.t.max() >= self.horizon:
            raise ValueError(f"episode over (horizon {self.horizon} reached); expected reset() before step()")
        B, N, alive, everyone = self.num_envs, self.num_agents, self.alive, self._everyone
        # rotor model: target throttle sqrt((c+1)/2), first-order lag, thrust = throttle² f_max
        throttle = self.throttle + HUMMINGBIRD["rotor_lag"] * (np.sqrt((cmd + 1) * 0.5) - self.throttle)
        if not everyone:
            throttle *= alive[..., None]
            gone = ~alive  # park whoever left: zero velocity, own spot far above the map
            self._q3[gone] = np.broadcast_to(self._park, (B, N, 7))[gone]
            self._v3[gone] = 0.0
        self.throttle = throttle
        self._ctrl[:] = (throttle * throttle * MAX_THRUST).reshape(B, -1)
        rec = self.batch.rollout(SUBSTEPS, record=("sensordata",), out=self._rec)["sensordata"]
        pos, half = self._q3[..., :3], self.scenario.world_size / 2
        self.t = self.t + 1
        leaving = None
        if rec.any() or np.abs(pos[..., :2]).max() > half or pos[..., 2].max() > CEILING:
            sens = rec.max(axis=1)  # contacts (B, 2N): [any, floor] per drone, max over substeps
            out = (np.abs(pos[..., :2]) > half).any(-1) | (pos[..., 2] > CEILING)
            touch_any, touch_floor = sens[:, 0::2], sens[:, 1::2]
            drone_contacts = (touch_any - touch_floor) * alive
            self.agent_collisions = ((drone_contacts + touch_floor + out) * alive).astype(np.int64)
            self.collisions = (np.rint(drone_contacts.sum(1) / 2)
                               + ((touch_floor + out) * alive).sum(1)).astype(np.int64)
            leaving = alive & (self.agent_collisions > 0)
        elif self.collisions.any():
            self.collisions, self.agent_collisions = np.zeros(B, np.int64), np.zeros((B, N), np.int64)
        if self.scenario.varying and (self.t == self.scenario.change_step).any():
            drop = alive & ~self._keep & (self.t == self.scenario.change_step)[:, None]
            leaving = drop if leaving is None else leaving | drop
        if leaving is not None and leaving.any():
            self._frozen[leaving] = self._state()[leaving]
            self.alive = alive & ~leaving
            self._everyone = False
        self._update_coverage()
        return self.observe(), self.info()

    def _check_actions(self, actions) -> np.ndarray:
        B, N = self.num_envs, self.num_agents
        if torch.is_tensor(actions):
            if not actions.dtype.is_floating_point:
                raise ValueError(f"actions: expected a float tensor of motor commands, got dtype {actions.dtype}")
            actions = (actions.detach() if actions.requires_grad else actions).cpu().numpy()
        elif isinstance(actions, np.ndarray):
            if not np.issubdtype(actions.dtype, np.floating):
                raise ValueError(f"actions: expected a float array of motor commands, got dtype {actions.dtype}")
        else:
            raise ValueError(f"actions: expected a float tensor of shape ({B}, {N}, 4), got {type(actions).__name__}")
        if actions.shape != (B, N, 4):
            raise ValueError(f"actions: expected shape (num_envs, num_agents, 4) = ({B}, {N}, 4), got {actions.shape}")
        a = actions.astype(np.float64, copy=False)
        if not np.abs(a).max() <= 1.0:  # one reduction in the common case; NaN fails it too
            if not np.isfinite(a).all():
                raise ValueError("actions: expected finite motor commands, got NaN or inf")
            raise ValueError(f"actions: expected motor commands in [-1, 1], got values in "
                             f"[{a.min():.3g}, {a.max():.3g}]")
        return a

    def _state(self) -> np.ndarray:
        """(B, N, 13): position, quaternion (w x y z), linear velocity, body angular velocity."""
        B, N = self.num_envs, self.num_agents
        return np.concatenate([self._qpos.reshape(B, N, 7), self._qvel.reshape(B, N, 6)], axis=-1)

    def _update_coverage(self):
        """Covered/reached landmarks, then the tensors that ``observe`` and ``info`` hand out."""
        st = np.concatenate([self._q3, self._v3, self.throttle], -1)
        if not self._everyone:
            st[..., :13] = np.where(self.alive[..., None], st[..., :13], self._frozen)
        self.state = s = st[..., :13]
        diff = s[:, :, None, :3] - self.landmark_pos[:, None]                        # (B, N, L, 3)
        near = np.einsum("bnlk,bnlk->bnl", diff, diff) <= self.reach_distance ** 2
        self.covered = (near if self._everyone else near & self.alive[..., None]).any(axis=1)
        self.reached = self.reached | self.covered
        # numpy slices wrapped by torch.from_numpy: cheaper than slicing tensors. Every array
        # handed out here is replaced, never written in place, afterwards (reset copies first),
        # so arrays that change only on events (landmarks, alive, contacts) keep their tensors.
        if self.dtype == torch.float32:
            st = st.astype(np.float32)
        T, same = (torch.from_numpy if self.device.type == "cpu" else self._tensor), self._same
        alive, covered, reached, t = same("alive"), T(self.covered), T(self.reached), T(self.t)
        self._obs = {"agent_pos": T(st[..., :3]), "agent_vel": T(st[..., 7:10]), "agent_quat": T(st[..., 3:7]),
                     "agent_angvel": T(st[..., 10:13]), "throttle": T(st[..., 13:17]),
                     "landmark_pos": same("landmark_pos"), "obstacle_pos": self._no_obstacles, "alive": alive,
                     "covered": covered, "reached": reached, "t": t}
        self._info = {"covered": covered, "reached": reached, "collisions": same("collisions"),
                      "agent_collisions": same("agent_collisions"), "alive": alive,
                      "done": T(self.t >= self.horizon), "t": t}

    def _same(self, name: str) -> torch.Tensor:
        """The tensor of array attribute ``name``, rebuilt only when the array was replaced."""
        arr = getattr(self, name)
        held = self._held.get(name)
        if held is None or held[0] is not arr:
            a = arr.astype(np.float32) if arr.dtype == np.float64 and self.dtype == torch.float32 else arr
            held = self._held[name] = (arr, self._tensor(a))
        return held[1]

    def _tensor(self, a: np.ndarray) -> torch.Tensor:
        t = torch.from_numpy(a)
        return t if self.device.type == "cpu" else t.to(self.device)

    # ------------------------------------------------------------- observing
    @property
    def done(self) -> torch.Tensor:
        return self._info["done"]

    def observe(self) -> dict[str, torch.Tensor]:
        """The observation dict (see the module docstring); tensors are fresh every step."""
        return dict(self._obs)

    def info(self) -> dict[str, torch.Tensor]:
        return dict(self._info)

    def __repr__(self):
        sc = self.scenario
        return (f"DroneWorld({sc.name!r}, num_envs={self.num_envs}, num_agents={sc.num_agents}, "
                f"world_size={sc.world_size:g}, horizon={sc.horizon}, device={str(self.device)!r})")
