"""What both worlds' PettingZoo faces share: spaces by agent, the world, reset options."""
from __future__ import annotations

import difflib
import warnings

from pettingzoo import ParallelEnv

from ..checks import reset_options

__all__ = ["WorldParallelEnv"]


class WorldParallelEnv(ParallelEnv):
    """What both worlds' PettingZoo faces share: spaces by agent, the world, reset options."""

    reset_options: tuple[str, ...] = ()
    """The reset options this face understands (a near miss of one is an error, others warn)."""

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @property
    def world(self):
        """The underlying batched world (``num_envs == 1``)."""
        return self._world

    def _known_options(self, options: dict | None) -> dict:
        """The understood reset options.

        An unknown key that is a near miss of an understood one (``agent_position`` for
        ``agent_pos``) is one clear error, as in the batched world: it is a typo, and ignoring
        it would start an episode the caller did not ask for. Any other unknown key is ignored
        with a warning, because PettingZoo's API lets options be environment-specific and its
        own ``parallel_api_test`` resets with ``options={"options": 1}``."""
        options = reset_options(options)
        unknown = sorted(set(options) - set(self.reset_options), key=str)
        for key in unknown:
            near = difflib.get_close_matches(str(key), list(self.reset_options), n=1, cutoff=0.6)
            if near:
                raise ValueError(f"reset: unknown option {key!r}; did you mean {near[0]!r}? understood options "
                                 f"are {list(self.reset_options)}")
        if unknown:
            warnings.warn(f"reset: ignoring unknown option(s) {unknown}; understood options are "
                          f"{list(self.reset_options)}", stacklevel=3)
        return {k: v for k, v in options.items() if k in self.reset_options}
