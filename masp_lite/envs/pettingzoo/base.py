"""What both worlds' PettingZoo faces share: spaces by agent, the world, reset options."""
from __future__ import annotations

import warnings

from pettingzoo import ParallelEnv

__all__ = ["WorldParallelEnv"]


class WorldParallelEnv(ParallelEnv):
    """What both worlds' PettingZoo faces share: spaces by agent, the world, reset options."""

    reset_options: tuple[str, ...] = ()
    """The reset options this face understands; others are ignored with a warning."""

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @property
    def world(self):
        """The underlying batched world (``num_envs == 1``)."""
        return self._world

    def _known_options(self, options: dict | None) -> dict:
        """The understood reset options. Unknown keys only warn: PettingZoo's own API test
        resets with ``options={"options": 1}``."""
        options = dict(options or {})
        unknown = sorted(set(options) - set(self.reset_options))
        if unknown:
            warnings.warn(f"reset: ignoring unknown option(s) {unknown}; understood options are "
                          f"{list(self.reset_options)}", stacklevel=3)
        return {k: v for k, v in options.items() if k in self.reset_options}
