"""Training settings, one dataclass per concern.

* :class:`NetConfig` — MASP's architecture; stored with the weights and read back from
  them (:mod:`masp_lite.weights`), so a weights file rebuilds its own networks;
* :class:`PPOConfig` — MAPPO's optimisation settings (MAGE-X's defaults);
* :class:`RewardConfig` — the weights of R_CAE (eq. 5) and R_GM's reference (eq. 1);
  the shipped weights until 2026-12 were trained with ``gm_reference="squared"`` (then
  spelt ``gm_reference_power=2``);
* :class:`RunConfig` — the schedule: worlds, updates, stages, evaluation, checkpoints;
* :class:`ImitationConfig` — imitation for the Goal Matcher in place of MAPPO (``masp-minmax``'s first stages);
* :class:`TrainConfig` — the parts together. Its field names are unique across the
  parts, so ``--set lr=2e-4`` needs no prefix and a manifest stores one flat dict.

Every command's ``--set KEY=VALUE`` converts a value by the type of the field it sets
(:func:`masp_lite.parsing.parse_sets`) — the annotations below are real types (no
postponed evaluation) for that reason.
Only settings that the shipped weights use are here; the ones tried and not kept are in
``docs/research-log.md``.
"""
import dataclasses
import math
from dataclasses import dataclass, field

__all__ = ["NetConfig", "PPOConfig", "RewardConfig", "RunConfig", "ImitationConfig", "TrainConfig"]


GM_REFERENCES = ("distance", "squared")
"""The settings of :attr:`RewardConfig.gm_reference`."""
GOAL_MATCHERS = ("graph", "mlp", "random", "hungarian", "none")
EXECUTORS = ("graph", "mlp", "nearest", "subgraph", "attention", "radius")
ACTIONS = ("discrete", "throttle", "velocity")
"""The settings of :attr:`NetConfig.goal_matcher`, :attr:`NetConfig.executor` and :attr:`NetConfig.action`."""
TEACHERS = ("none", "h-bottleneck")
"""The settings of :attr:`ImitationConfig.imitate`."""


def _check(obj, name, low=None, high=None, integer=False):
    v = getattr(obj, name)
    if integer:
        if isinstance(v, bool) or not isinstance(v, int) or (low is not None and v < low):
            raise ValueError(f"{name}: expected an int >= {low}, got {v!r}")
        return
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or \
            (low is not None and v < low) or (high is not None and v > high):
        bounds = f"in [{low}, {high}]" if high is not None else f">= {low}"
        raise ValueError(f"{name}: expected a finite number {bounds}, got {v!r}")


@dataclass(frozen=True)
class NetConfig:
    """MASP's architecture (paper, section "Methodology"); saved with the weights as ``arch``."""

    width: int = 32
    """Feature width L of every network."""
    group_size: int = 3
    """N_g, agents per group in the Group Information Fusion (agent k plus N_g - 1 others)."""
    gcn_layers: int = 1
    """GCN layers per group subgraph."""
    obstacles_seen: int = 2
    """Nearest obstacles the executor sees."""
    global_step: int = 3
    """Environment steps per Goal Matcher decision (3 in the paper)."""
    goal_matcher: str = "graph"
    """The high level (the paper's ablations and baselines): ``graph``, MASP's Goal Matcher;
    ``mlp``, "GM w.o. Graph" (:class:`~masp_lite.nets.ablations.GoalMatcherMLP`); ``random``,
    "MASP w. RG": distinct random goals, no Goal Matcher trained; ``hungarian``, the Hungarian
    assignment every global step, nothing trained (``h-mappo``); ``none``, no goals at all: the
    executor sees every landmark and is trained on a coverage reward (``mappo``, ``darl1n``)."""
    executor: str = "graph"
    """The executor's view of the other agents: ``graph``, the Group Information Fusion;
    ``mlp``, "CAE w.o. Graph" (:class:`~masp_lite.nets.ablations.FusionMLP`); ``nearest``,
    ``subgraph``, ``attention`` and ``radius``, the RL baselines' views (:mod:`masp_lite.nets.baselines`)."""
    neighbours_seen: int = 3
    """Other agents the ``nearest`` and ``subgraph`` executors see."""
    team_size: int = 0
    """Agents an ``mlp`` variant is built for (its input size is fixed); 0 for the graph networks,
    which serve any team size. Training sets it to the scenario's team size."""
    action: str = "discrete"
    """What the executor outputs, and so which world the networks are for: ``discrete``, one of
    MPE's 5 actions (particle worlds); ``throttle``, the 4 motor commands of a drone (the paper's
    drone action), or ``velocity``, a velocity set-point the geometric controller flies (the
    variant ``masp-velocity``); both drone actions are Gaussian (:mod:`masp_lite.nets.drones`)."""
    log_std_init: float = -1.6
    """Initial log standard deviation of the drone executor's Gaussian (per action dimension)."""

    def __post_init__(self):
        for name in ("width", "gcn_layers", "obstacles_seen", "global_step", "neighbours_seen"):
            _check(self, name, 1, integer=True)
        _check(self, "group_size", 2, integer=True)
        _check(self, "team_size", 0, integer=True)
        if self.goal_matcher not in GOAL_MATCHERS:
            raise ValueError(f"goal_matcher: expected one of {list(GOAL_MATCHERS)}, got {self.goal_matcher!r}")
        if self.executor not in EXECUTORS:
            raise ValueError(f"executor: expected one of {list(EXECUTORS)}, got {self.executor!r}")
        if self.action not in ACTIONS:
            raise ValueError(f"action: expected one of {list(ACTIONS)}, got {self.action!r}")
        if not isinstance(self.log_std_init, (int, float)) or not -10 <= self.log_std_init <= 2:
            raise ValueError(f"log_std_init: expected a number in [-10, 2], got {self.log_std_init!r}")

    @property
    def fixed_size(self) -> bool:
        """Whether a network takes a fixed number of agents (an ``mlp`` variant)."""
        return "mlp" in (self.goal_matcher, self.executor)

    @property
    def world(self) -> str:
        """``"particle"`` or ``"drone"``: the world kind these networks act in (from :attr:`action`)."""
        return "particle" if self.action == "discrete" else "drone"


@dataclass
class PPOConfig:
    """MAPPO's settings for both levels (defaults: MAGE-X's)."""

    lr: float = 7e-4
    """Adam learning rate, all four networks."""
    ppo_epochs: int = 4
    """Passes over each rollout (executor)."""
    gm_ppo_epochs: int = 10
    """Passes over each rollout for the Goal Matcher (its rollouts are 3x shorter and cheap)."""
    num_minibatches: int = 2
    """Minibatches per pass (rows are (step, world) pairs)."""
    clip: float = 0.2
    """PPO ratio clip (policy) and value clip."""
    entropy_coef: float = 0.01
    """Entropy bonus weight."""
    value_coef: float = 1.0
    """Value loss weight."""
    huber_delta: float = 10.0
    """Huber loss threshold for the value loss."""
    max_grad_norm: float = 10.0
    """Gradient norm clip per network group."""
    gamma: float = 0.99
    """Executor discount per environment step."""
    gae_lambda: float = 0.95
    """GAE lambda (both levels)."""
    gm_gamma: float = 0.5
    """Goal Matcher discount per global step (its reward, eq. 1, is nearly immediate)."""

    def __post_init__(self):
        for name in ("ppo_epochs", "gm_ppo_epochs", "num_minibatches"):
            _check(self, name, 1, integer=True)
        for name in ("gamma", "gae_lambda", "gm_gamma"):
            _check(self, name, 0.0, 1.0)
        for name in ("entropy_coef", "value_coef"):
            _check(self, name, 0.0)
        # a step above 1 or a clip above 1 cannot train (every ratio would pass); checked up front so that
        # a run never starts only to write non-finite weights
        for name, high in (("lr", 1.0), ("clip", 1.0), ("huber_delta", None), ("max_grad_norm", None)):
            _check(self, name, 0.0, high)
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: expected a positive number, got {getattr(self, name)!r}")


@dataclass
class RewardConfig:
    """Weights of MASP's rewards (paper, eqs. 1 and 5)."""

    bonus_coef: float = 1.0
    """alpha in R_CAE: weight of the complete bonus R_b."""
    distance_coef: float = 1.0
    """beta in R_CAE: weight of the distance penalty R_d."""
    collision_coef: float = 1.0
    """gamma in R_CAE: weight of the collision penalty R_c."""
    gm_reference: str = "distance"
    """R_GM's reference assignment and the cost ``D`` it is scored by (eq. 1): ``distance``,
    the Hungarian assignment on distances (the paper's reading); ``squared``, on squared
    distances (shorter longest trips). The paper does not give the reference's costs (the
    min-max reference, tried and not kept, is in ``docs/research-log.md``)."""

    def __post_init__(self):
        for name in ("bonus_coef", "distance_coef", "collision_coef"):
            _check(self, name, 0.0)
        if self.gm_reference not in GM_REFERENCES:
            raise ValueError(f"gm_reference: expected one of {list(GM_REFERENCES)}, got {self.gm_reference!r}")


@dataclass
class RunConfig:
    """The schedule of one training run."""

    num_envs: int = 64
    """Worlds simulated side by side; one rollout is one episode of each."""
    updates: int = 200
    """PPO updates (rollouts) in the whole run; may grow when a run is resumed."""
    train_executor: bool = True
    """Update the executor; ``false`` trains only the Goal Matcher (a cheap fine-tuning stage)."""
    eval_every: int = 10
    """Updates between evaluations (0: only at the end)."""
    eval_episodes: int = 32
    """Episodes per evaluation (deterministic policies, fixed evaluation seed)."""
    checkpoint_every: int = 5
    """Updates between checkpoints of the training state."""

    def __post_init__(self):
        for name in ("num_envs", "updates", "eval_episodes", "checkpoint_every"):
            _check(self, name, 1, integer=True)
        _check(self, "eval_every", 0, integer=True)
        if not isinstance(self.train_executor, bool):
            raise ValueError(f"train_executor: expected true or false, got {self.train_executor!r}")


@dataclass
class ImitationConfig:
    """The Goal Matcher taught a teacher's assignment instead of MAPPO (ours): :mod:`masp_lite.algos.imitation`,
    on ``num_envs`` fresh episode starts an iteration."""

    imitate: str = "none"
    """The teacher: ``none`` (MAPPO, the paper's training) or ``h-bottleneck``'s min-max assignment."""
    imitation_margin: float = 4.0
    """The margin per agent sent past the teacher's longest trip (squared nats of the decoding's cost)."""

    def __post_init__(self):
        if self.imitate not in TEACHERS:
            raise ValueError(f"imitate: expected one of {list(TEACHERS)}, got {self.imitate!r}")
        _check(self, "imitation_margin", 0.0)


_PARTS = {"net": NetConfig, "ppo": PPOConfig, "reward": RewardConfig, "run": RunConfig, "imitation": ImitationConfig}


@dataclass
class TrainConfig:
    """Everything a training run is configured by; ``flat()`` is what manifests store."""

    net: NetConfig = field(default_factory=NetConfig)
    """Architecture (:class:`NetConfig`)."""
    ppo: PPOConfig = field(default_factory=PPOConfig)
    """Optimisation (:class:`PPOConfig`)."""
    reward: RewardConfig = field(default_factory=RewardConfig)
    """Rewards (:class:`RewardConfig`)."""
    run: RunConfig = field(default_factory=RunConfig)
    """Schedule (:class:`RunConfig`)."""
    imitation: ImitationConfig = field(default_factory=ImitationConfig)
    """Imitation for the Goal Matcher (:class:`ImitationConfig`); none by default."""

    @classmethod
    def keys(cls) -> dict[str, str]:
        """Every setting's name -> the part it belongs to (``"lr" -> "ppo"``)."""
        return {f.name: part for part, c in _PARTS.items() for f in dataclasses.fields(c)}

    @classmethod
    def from_flat(cls, values: dict) -> "TrainConfig":
        """Build from ``{name: value}``; a name that is no setting is one clear error."""
        keys = cls.keys()
        unknown = sorted(set(values) - set(keys))
        if unknown:
            raise ValueError(f"unknown training setting(s) {unknown}; expected some of {sorted(keys)}")
        parts = {part: {} for part in _PARTS}
        for name, value in values.items():
            parts[keys[name]][name] = value
        return cls(**{part: c(**parts[part]) for part, c in _PARTS.items()})

    def flat(self) -> dict:
        """``{name: value}`` of every setting (the inverse of :meth:`from_flat`)."""
        return {k: v for part in _PARTS for k, v in dataclasses.asdict(getattr(self, part)).items()}
