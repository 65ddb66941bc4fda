"""masp-lite: a laptop-scale course and reference implementation of MASP.

MASP (Multi-Agent Scalable Graph-based Planner) assigns goals with a graph-based Goal
Matcher and reaches them with a Coordinated Action Executor built on Group Information
Fusion, both trained with MAPPO. See ``notebooks/`` for the course.

Reading path — MASP itself, in the order of the paper's method section (13 files, about
2,183 lines; each reads in one sitting):

=====  ==========================  =====  ================================================
step   file                        lines  what it holds
=====  ==========================  =====  ================================================
1      ``envs/particle.py``          313  the task: MPE's world, batched over episodes
2      ``evaluation/metrics.py``     109  SR, Steps, CR, as the paper defines them
3      ``algos/assignment.py``       158  the Hungarian assignment (R_GM's reference)
4      ``nets/encoders.py``          157  Self-Encoder and Cross-Encoder (eqs. 2-4)
5      ``nets/fusion.py``            149  Group Information Fusion: groups of 3, a GCN each
6a     ``nets/features.py``          120  what the networks see of a world (both worlds)
6b     ``nets/masp.py``              236  Goal Matcher, executor, critics (both worlds)
7      ``nets/goal_draw.py``          85  matching scores -> distinct goals, in training
8      ``nets/decoding.py``           84  matching scores -> distinct goals, when acting
9      ``algos/rewards.py``           97  R_GM (eq. 1) and R_CAE (eq. 5)
10     ``algos/mappo.py``            241  MAPPO: GAE, clipped surrogate, value normalisation
11     ``algos/masp_trainer.py``     263  one rollout loop and both levels' PPO updates
12     ``policies/masp.py``          171  the trained networks acting in a world
=====  ==========================  =====  ================================================

Beside the path, not inside it: the ablations' and baselines' parts (``nets/variants.py``,
``nets/ablations.py``, ``nets/baselines.py``, ``algos/goal_sources.py``), the chunked CPU
kernels that compute the encoders' and fusion's numbers faster in training (``nets/kernels.py``), the
team-size protocols of the scripted methods (``algos/team.py``), the drones (``envs/drones.py``,
``nets/drones.py``, ``algos/drone_trainer.py``), the method table (``policies/__init__.py``),
how every kept weights file is trained (``recipes.py``: each method's stages as data) and the
reproduction room (``reproduction/``: the paper's numbers, tables, claims and
training plan, the only code that knows the repository's ``results/``).
"""
import os as _os
import sys as _sys

__version__ = "0.1.0"

# Before anything imports torch: its OpenMP threads sleep instead of spinning while they wait, so they never fight
# another busy program for a core (masp_lite.threads says why). A user's own setting wins; None: torch came first.
_torch_wait_policy = None if "torch" in _sys.modules else _os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
