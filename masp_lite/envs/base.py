"""What every batched world shares, written once: argument checks, env ids, reset options (checked
by :mod:`.start` when given), the team mask of a team-size change, rejection-sampled spawns and
the action checks.

:class:`BatchedWorld` is the interface :mod:`masp_lite.evaluation` and the policies rely
on: ``num_envs`` episodes of one :class:`~masp_lite.envs.scenarios.Scenario`, stepped
together; ``reset(seed=None, options=None, env_ids=None) -> obs``,
``step(actions) -> (obs, info)``, ``observe()``, ``info()`` and ``done``. The particle
world computes in torch and the drone world in numpy (MuJoCo's arrays), so the helpers
here take either; each world keeps its own random generator, so the numbers it draws
are exactly those it drew before this base existed.
"""
from __future__ import annotations

import numpy as np
import torch

from .scenarios import Scenario, get_scenario

__all__ = ["BatchedWorld", "MAX_TRIES"]

MAX_TRIES = 10_000
"""Rejection-sampling draws per body before a spawn is declared impossible."""


class BatchedWorld:
    """Base of :class:`~masp_lite.envs.particle.ParticleWorld` and :class:`~masp_lite.envs.drones.DroneWorld`."""

    kind: str = ""
    """The :attr:`Scenario.kind` this world simulates."""
    reset_options: dict[str, int] = {}
    """Start-state options of ``reset`` (besides ``keep``): name -> size of the last axis."""

    def _setup(self, scenario, num_envs, device, dtype, overrides) -> Scenario:
        """Check the constructor's arguments and set ``scenario``, ``num_envs``, ``device``, ``dtype``."""
        sc = self.scenario = get_scenario(scenario, **overrides)
        if sc.kind != self.kind:
            prefix = "mpe-*" if self.kind == "particle" else f"{self.kind}-*"
            raise ValueError(f"scenario {sc.name!r} is a {sc.kind} scenario; expected a {self.kind} "
                             f"scenario ({prefix})")
        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f"num_envs: expected a positive int, got {num_envs!r}")
        if dtype not in (torch.float32, torch.float64):
            raise ValueError(f"dtype: expected torch.float32 or torch.float64, got {dtype}")
        try:
            self.device = torch.device(device)
        except (RuntimeError, TypeError) as e:
            raise ValueError(f"device: expected a torch device such as 'cpu' or 'cuda', got {device!r}") from e
        if self.device.type not in ("cpu", "cuda"):  # 'meta' holds no numbers; others are untested
            raise ValueError(f"device {str(device)!r}: expected 'cpu' or 'cuda' (a world computes real numbers)")
        from .checks import check_world_memory
        check_world_memory(num_envs, sc.num_agents)
        if self.device.type == "cuda" and not torch.cuda.is_available():
            why = "this torch build has no CUDA" if torch.version.cuda is None else "no CUDA device is visible"
            raise ValueError(f"device {str(device)!r}: {why} (torch {torch.__version__}); expected 'cpu'")
        self.num_envs, self.dtype = int(num_envs), dtype
        self.num_agents = self.num_landmarks = sc.num_agents
        self.num_obstacles, self.horizon = sc.num_obstacles, sc.horizon
        return sc

    # ------------------------------------------------------------------ reset
    def _env_ids(self, env_ids) -> np.ndarray:
        """The episodes a reset touches, as int64 indices (all when ``env_ids`` is None).

        ``env_ids`` is either integer indices or a bool mask of shape ``(num_envs,)`` (as VMAS
        and TorchRL pass ``done``): a mask resets exactly the worlds it marks. Floats, other
        dtypes and masks of another length are one clear error."""
        if env_ids is None:
            return np.arange(self.num_envs)
        if torch.is_tensor(env_ids) and env_ids.dtype == torch.uint8:
            raise ValueError("env_ids: a torch.uint8 tensor could be a mask (old torch) or indices; expected a "
                             f"bool mask of shape ({self.num_envs},) or int64 indices")
        raw = np.asarray(env_ids.cpu() if torch.is_tensor(env_ids) else env_ids)
        if raw.dtype == bool:
            if raw.shape != (self.num_envs,):
                raise ValueError(f"env_ids: a bool mask must have shape ({self.num_envs},), got {raw.shape}")
            return np.flatnonzero(raw).astype(np.int64)
        if raw.size and not np.issubdtype(raw.dtype, np.integer):
            raise ValueError(f"env_ids: expected integer indices or a bool mask of shape ({self.num_envs},), "
                             f"got dtype {raw.dtype}")
        ids = raw.astype(np.int64).reshape(-1)
        if len(ids) and (ids.min() < 0 or ids.max() >= self.num_envs):
            raise ValueError(f"env_ids: expected indices in [0, {self.num_envs}), got {ids.tolist()}")
        return ids

    def _start_state(self, options: dict, n: int) -> dict[str, np.ndarray]:
        """Validated start-state options for ``n`` episodes (:func:`~masp_lite.envs.start.start_state`);
        ``{}`` when none are given, without loading the checks (training never gives any)."""
        if not options:
            return {}
        from .start import start_state
        return start_state(self, options, n)

    def _option_bounds(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) per coordinate of a start-state option (broadcast over its last axis).

        A start far outside the world is refused rather than simulated: the physics would
        overflow (particles) or silently reset the body (MuJoCo)."""
        return np.array(-np.inf), np.array(np.inf)

    def _random_order(self, n: int) -> np.ndarray:
        """(n, N) a random order of the agents per episode, from the world's generator."""
        raise NotImplementedError

    def _team_mask(self, n: int, keep) -> np.ndarray:
        """(n, N) bool: the agents that stay after the team-size change.

        ``keep`` (the reset option, (N,) or (n, N) bool) says it; otherwise a fixed team keeps
        everyone and a shrinking one keeps ``team_after`` agents drawn at random."""
        sc, N = self.scenario, self.num_agents
        if keep is not None:
            k = np.asarray(keep.cpu() if torch.is_tensor(keep) else keep)
            if k.dtype != bool or k.shape not in ((N,), (n, N)):
                raise ValueError(f"reset option 'keep': expected a bool array of shape ({N},), "
                                 f"got {k.shape} {k.dtype}")
            return np.broadcast_to(k, (n, N)).copy()
        if not sc.varying:
            return np.ones((n, N), bool)
        mask = np.zeros((n, N), bool)
        np.put_along_axis(mask, self._random_order(n)[:, : sc.team_after], True, axis=1)
        return mask

    def _place(self, out, draw, clear, what: str):
        """Rejection sampling, vectorized over episodes: fill ``out[:, i]`` for every body ``i``.

        ``draw(m)`` gives ``m`` candidate positions; ``clear(todo, cand, i)`` says which
        candidates keep their distances (to other bodies and to bodies ``0 .. i-1``) for
        episodes ``todo``. ``out`` is a numpy array or a torch tensor; so are the others."""
        n, count = out.shape[:2]
        arange = torch.arange if torch.is_tensor(out) else np.arange
        for i in range(count):
            todo = arange(n)
            for _ in range(MAX_TRIES):
                cand = draw(len(todo))
                ok = clear(todo, cand, i)
                out[todo[ok], i] = cand[ok]
                todo = todo[~ok]
                if len(todo) == 0:
                    break
            else:
                raise ValueError(f"could not place {what} in a {self.scenario.world_size:g} m map; "
                                 "expected a larger world_size")
        return out

    # ------------------------------------------------------------------- step
    def _check_actions(self, actions, integer: bool, tail: tuple = ()):
        """Check the type, dtype family and shape of ``actions``; returns them unchanged.

        Integer action ids for the particle world, float motor commands for drones; shape
        ``(num_envs, num_agents, *tail)``; a numpy array or a torch tensor."""
        shape = (self.num_envs, self.num_agents, *tail)
        kind, what = ("an integer", "action ids") if integer else ("a float", "motor commands")
        if torch.is_tensor(actions):
            dt = actions.dtype
            ok = (not dt.is_floating_point and not dt.is_complex and dt != torch.bool) if integer \
                else dt.is_floating_point
        elif isinstance(actions, np.ndarray):
            ok = np.issubdtype(actions.dtype, np.integer if integer else np.floating)
        else:
            raise ValueError(f"actions: expected {kind} tensor of {what} with shape {shape}, "
                             f"got {type(actions).__name__}")
        if not ok:
            raise ValueError(f"actions: expected {kind} tensor of {what}, got dtype {actions.dtype}")
        if tuple(actions.shape) != shape:
            names = "(num_envs, num_agents" + (", 4)" if tail else ")")
            raise ValueError(f"actions: expected shape {names} = {shape}, got {tuple(actions.shape)}")
        return actions

    # ------------------------------------------------------------- observing
    def __repr__(self):
        sc = self.scenario
        extra = f", num_obstacles={sc.num_obstacles}" if self.kind == "particle" else ""
        world = "".join(f", {k}={v!r}" for k, v in sc.world.items())
        return (f"{type(self).__name__}({sc.name!r}, num_envs={self.num_envs}, num_agents={sc.num_agents}"
                f"{extra}, world_size={sc.world_size:g}, horizon={sc.horizon}{world}, "
                f"device={str(self.device)!r})")
