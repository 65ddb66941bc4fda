"""The checks of a world's arguments that take more than a line: seeds, the type of reset options,
arrays of real numbers, the memory a batch of worlds needs.

Loaded by the worlds when first used (as :mod:`.start` is), so importing the trainer stays small.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import torch

__all__ = ["check_seed", "reset_options", "real_array", "check_world_memory", "WORLD_PAIR_BYTES"]

WORLD_PAIR_BYTES = 64
"""The world's own memory per agent pair and world (distances, contacts, masks), roughly: its N^2 part."""


def check_seed(seed, what: str = "seed") -> int | None:
    """``seed`` as an int in [0, 2**63 - 1] (``None`` stays ``None``); else one ValueError.

    A negative seed would wrap (``-1`` is ``2**64 - 1`` to torch), ``1.5`` would act as 1 and
    ``"3"`` as 3: each is refused rather than read as another seed."""
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2 ** 63:
        raise ValueError(f"{what}: expected an int from 0 to 2**63 - 1 (or None), got {seed!r}")
    return int(seed)


def reset_options(options) -> dict:
    """``reset``'s ``options`` as a dict (``None`` is none); anything but a mapping is one clear error."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(f"reset options: expected a dict such as {{'agent_pos': ...}} or None, got a "
                         f"{type(options).__name__}")
    return dict(options)


def real_array(value, what: str) -> np.ndarray:
    """``value`` (array, tensor or nested list) as float64 when it holds real numbers; else one ValueError naming
    ``what`` (complex numbers would lose their imaginary part, objects and strings are no numbers at all)."""
    try:
        a = np.asarray(value.detach().cpu().numpy() if torch.is_tensor(value) else value)
    except (ValueError, TypeError, RuntimeError) as e:
        raise ValueError(f"{what}: expected an array of real numbers ({e})") from None
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{what}: expected real numbers, got dtype {a.dtype}")
    return a.astype(np.float64)


def _available_bytes() -> int | None:
    """Memory this machine can still give (``MemAvailable`` of /proc/meminfo), ``None`` where unknown."""
    try:
        with open("/proc/meminfo", "rb") as f:
            for line in f.read(1 << 16).decode().splitlines():
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def check_world_memory(num_envs: int, num_agents: int) -> None:
    """One ValueError, before anything is allocated, when ``num_envs`` worlds of ``num_agents`` agents would
    need more memory than is available (``make(num_envs=10**7)`` would otherwise stall or crash)."""
    need, have = WORLD_PAIR_BYTES * int(num_envs) * num_agents ** 2, _available_bytes()
    if have is not None and need > have:
        raise ValueError(f"num_envs={num_envs}: {num_envs} worlds of {num_agents} agents need about "
                         f"{need / 2 ** 30:.1f} GiB (~{WORLD_PAIR_BYTES} bytes per agent pair and world), more "
                         f"than the {have / 2 ** 30:.1f} GiB available; expected fewer worlds")
