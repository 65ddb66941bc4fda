"""Named scenario presets (the paper's testbeds) and their validated overrides.

A :class:`Scenario` is a frozen record of everything that defines a navigation task:
team size, obstacles, map, horizon and an optional team-size change. The presets follow
the paper's "Testbeds" section:

==============  ======  =========  ========  =======  ===========================
name            agents  obstacles  map (m²)  horizon  team change
==============  ======  =========  ========  =======  ===========================
``mpe-5``       5       5          4         18       —
``mpe-20``      20      10         64        45       —
``mpe-50``      50      30         400       90       —
``mpe-20to10``  20      10         64        45       20 ⇒ 10 at step 45 // 3
``mpe-50to20``  50      30         400       90       50 ⇒ 20 at step 90 // 3
``drone-5``     5       0          36        300      —
``drone-20``    20      0          256       500      —
``drone-20to10`` 20     0          256       500      20 ⇒ 10 at step 500 // 3
==============  ======  =========  ========  =======  ===========================

Past the paper's scale, :func:`same_density` gives a preset more agents at its density (``mpe-50``
with 500 agents: 300 obstacles, a 63.2 m side, 285 steps; 1000: 600, 89.4 m, 403 steps).

``world_size`` is the side of the square map in metres (``world_size ** 2`` is the
paper's map area); the map spans ``[-world_size / 2, world_size / 2]`` on each axis.
Landmarks always number ``num_agents`` (the paper keeps N1 landmarks when the team
shrinks).

Every ``mpe-*`` preset is the paper's world (:data:`PAPER_WORLD`): OpenAI MPE's
velocity-first update order and landmarks over the central 0.8× square, as in the code the
paper's descends from. Agents and obstacles spawn uniformly over the whole map, without
overlaps; the paper does not say where obstacles go, so they are placed as agents are.
``integration="mpe2", landmark_spawn="whole"`` (:data:`MPE2_WORLD`) is PettingZoo mpe2's
world, in which the particle world moves exactly as mpe2 does (the tests check it there).
"""
from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass

__all__ = ["Scenario", "SCENARIOS", "OVERRIDES", "get_scenario", "scenario_names", "PAPER_WORLD", "MPE2_WORLD",
           "world_name", "STARTS_FROM", "same_density"]


@dataclass(frozen=True)
class Scenario:
    """A navigation task. Every field can be overridden by keyword (see ``OVERRIDES``)."""

    name: str
    """Preset name the scenario was built from (``mpe-20``, ``drone-5``, …)."""
    kind: str
    """``"particle"`` (2-D MPE world) or ``"drone"`` (3-D MuJoCo world)."""
    num_agents: int
    """Team size at the start of an episode; also the number of landmarks."""
    num_obstacles: int
    """Immovable circular obstacles (particle world only)."""
    world_size: float
    """Side of the square map in metres; the map area is ``world_size ** 2``."""
    horizon: int
    """Environment steps per episode."""
    team_after: int | None = None
    """Team size after the change (``None``: the team never changes)."""
    change_step: int | None = None
    """Step after which the team shrinks; defaults to ``horizon // 3`` when ``team_after`` is set."""
    agent_radius: float = 0.1
    """Agent circle radius in metres (paper: 0.1)."""
    landmark_radius: float = 0.05
    """Landmark circle radius in metres (paper: 0.05)."""
    obstacle_radius: float = 0.1
    """Obstacle circle radius in metres (paper: 0.1)."""
    integration: str = "mpe2"
    """Particle world's update order. ``"velocity_first"`` (every ``mpe-*`` preset): the
    original OpenAI MPE's order, which the paper's code inherits (damp and push the velocity,
    then move with the new velocity), so a push already moves the agent in the step it is
    given. ``"mpe2"`` (the field's default, kept for the drone presets, which ignore it):
    PettingZoo's mpe2 today, position with the previous velocity, then the velocity."""
    landmark_spawn: str = "whole"
    """Where landmarks spawn: ``"central"`` (every ``mpe-*`` preset), the central 0.8× square
    (MAGE-X's navigation scenario: ``0.8 * uniform(-L/2, L/2)`` per axis), or the ``"whole"``
    map (uniform, as agents and obstacles; mpe2's simple_spread)."""
    collision_radius: float | None = None
    """Drones only: the radius of each drone's collision sphere, what a crash is tested against
    (``None``: the drone model's own, arm + rotor = 0.27 m). A larger sphere makes a world that
    punishes near passes (the research log's training margins); the planners keep their
    distances from the model's sphere. Particle agents collide at ``agent_radius``."""

    @property
    def world(self) -> dict:
        """The world definition every record and weights file stores: update order and
        landmark spawn (particle worlds); for drones ``{}``, or their ``collision_radius`` when it
        is set."""
        if self.kind != "particle":
            return {} if self.collision_radius is None else {"collision_radius": self.collision_radius}
        return {"integration": self.integration, "landmark_spawn": self.landmark_spawn}

    @property
    def varying(self) -> bool:
        """True when the team shrinks during the episode."""
        return self.team_after is not None

    @property
    def num_landmarks(self) -> int:
        return self.num_agents

    @property
    def area(self) -> float:
        return self.world_size**2

    @property
    def reach_distance(self) -> float:
        """An alive agent reaches a landmark when their centres are closer than this."""
        return self.agent_radius + self.landmark_radius


def _particle(name, n, k, area, horizon, team_after=None):
    return Scenario(name=name, kind="particle", num_agents=n, num_obstacles=k,
                    world_size=math.sqrt(area), horizon=horizon, team_after=team_after, **PAPER_WORLD)


def _drone(name, n, area, horizon, team_after=None):
    # A drone's size is its arm length (0.17 m, the Hummingbird's), so reach = 0.17 + 0.05 m.
    return Scenario(name=name, kind="drone", num_agents=n, num_obstacles=0,
                    world_size=math.sqrt(area), horizon=horizon, team_after=team_after,
                    agent_radius=0.17)


#: The paper's MPE world, which every ``mpe-*`` preset is: the update order and landmark
#: spawn of the code the paper's descends from (OpenAI MPE -> on-policy -> MAGE-X).
PAPER_WORLD = {"integration": "velocity_first", "landmark_spawn": "central"}
#: PettingZoo mpe2's world (``--set integration=mpe2 --set landmark_spawn=whole``), in which the
#: particle world moves exactly as mpe2's simple_spread; records and weights files that name no
#: world were made in it.
MPE2_WORLD = {"integration": "mpe2", "landmark_spawn": "whole"}

SCENARIOS: dict[str, Scenario] = {s.name: s for s in [
    _particle("mpe-5", 5, 5, 4.0, 18),
    _particle("mpe-20", 20, 10, 64.0, 45),
    _particle("mpe-50", 50, 30, 400.0, 90),
    _particle("mpe-20to10", 20, 10, 64.0, 45, team_after=10),
    _particle("mpe-50to20", 50, 30, 400.0, 90, team_after=20),
    _drone("drone-5", 5, 36.0, 300),
    _drone("drone-20", 20, 256.0, 500),
    _drone("drone-20to10", 20, 256.0, 500, team_after=10),
]}

#: The preset each team-change preset starts from: the same task until its team shrinks (``mpe-20to10`` is
#: ``mpe-20`` until step 15). Its size-invariant networks are that preset's (the paper's zero-shot protocol).
STARTS_FROM = {"mpe-20to10": "mpe-20", "mpe-50to20": "mpe-50", "drone-20to10": "drone-20"}

#: Update orders of the particle world (:attr:`Scenario.integration`).
INTEGRATIONS = ("mpe2", "velocity_first")
#: Landmark spawn regions of the particle world (:attr:`Scenario.landmark_spawn`).
LANDMARK_SPAWNS = ("whole", "central")


def world_name(world: dict) -> str:
    """A world definition in words, e.g. ``"integration=mpe2, landmark_spawn=whole"``."""
    return ", ".join(f"{k}={v}" for k, v in sorted(world.items())) or "the drone world"

#: Names accepted as overrides — every field of :class:`Scenario` but ``name`` and ``kind`` — with their
#: annotated types (``int | None`` for the team change): the one table ``--set`` converts values by and
#: :func:`get_scenario` checks them by.
OVERRIDES: dict[str, object] = {f.name: typing.get_type_hints(Scenario)[f.name] for f in dataclasses.fields(Scenario)
                                if f.name not in ("name", "kind")}


def scenario_names(kind: str | None = None) -> list[str]:
    """Valid preset names, optionally only those of one ``kind``."""
    return [n for n, s in SCENARIOS.items() if kind is None or s.kind == kind]


def get_scenario(name: str | Scenario, **overrides) -> Scenario:
    """Look up a preset and apply overrides, validating every value.

    >>> get_scenario("mpe-50", num_agents=100).num_agents
    100
    """
    if isinstance(name, Scenario):
        base = name
    else:
        if name not in SCENARIOS:
            raise ValueError(f"unknown scenario {name!r}; expected one of {sorted(SCENARIOS)}")
        base = SCENARIOS[name]
    unknown = sorted(set(overrides) - set(OVERRIDES))
    if unknown:
        raise ValueError(f"unknown override(s) {unknown}; valid overrides are {sorted(OVERRIDES)}")
    values = {}
    for key, value in overrides.items():
        args = typing.get_args(OVERRIDES[key])  # (int, NoneType) for ``int | None``
        if value is None and type(None) in args:
            values[key] = None
            continue
        cast = next((a for a in args if a is not type(None)), OVERRIDES[key])
        try:
            if isinstance(value, bool) or (cast is int and isinstance(value, float) and not value.is_integer()):
                raise TypeError
            values[key] = cast(value)
        except (TypeError, ValueError):
            raise ValueError(f"override {key}={value!r}: expected a {cast.__name__}") from None
    sc = dataclasses.replace(base, **values)
    # A bigger team changes the default team-size change only if the user did not say.
    if sc.team_after is not None and sc.change_step is None:
        sc = dataclasses.replace(sc, change_step=sc.horizon // 3)
    _validate(sc)
    return sc


def same_density(name: str, num_agents: int) -> dict:
    """The overrides that put ``num_agents`` agents at fixed-team preset ``name``'s density: area and obstacles
    per agent kept, the horizon grown as the map's side (``ceil(horizon * new side / side)``), as is the way to
    a landmark. Overrides, not presets: the preset's name still picks the weights a zero-shot test evaluates.

    >>> same_density("mpe-50", 1000)
    {'num_agents': 1000, 'num_obstacles': 600, 'world_size': 89.44271909999159, 'horizon': 403}
    """
    base = get_scenario(name)
    if base.varying or isinstance(num_agents, bool) or not isinstance(num_agents, int) or num_agents < 1:
        raise ValueError(f"same_density: expected a fixed-team preset and a positive int, got {name!r}, {num_agents!r}")
    side = base.world_size * math.sqrt(num_agents / base.num_agents)
    return {"num_agents": num_agents, "num_obstacles": round(base.num_obstacles * num_agents / base.num_agents),
            "world_size": side, "horizon": math.ceil(base.horizon * side / base.world_size)}


def _validate(sc: Scenario) -> None:
    def need(cond, what):
        if not cond:
            raise ValueError(f"scenario {sc.name!r}: expected {what}")

    need(sc.num_agents >= 1, f"num_agents >= 1, got {sc.num_agents}")
    need(sc.num_obstacles >= 0, f"num_obstacles >= 0, got {sc.num_obstacles}")
    need(sc.kind == "particle" or sc.num_obstacles == 0, "num_obstacles == 0 for drone scenarios")
    need(sc.world_size > 0 and math.isfinite(sc.world_size), f"world_size > 0, got {sc.world_size}")
    need(sc.horizon >= 1, f"horizon >= 1, got {sc.horizon}")
    need(sc.integration in INTEGRATIONS, f"integration in {INTEGRATIONS}, got {sc.integration!r}")
    need(sc.kind == "particle" or sc.integration == "mpe2", "integration 'mpe2' for drone scenarios")
    need(sc.landmark_spawn in LANDMARK_SPAWNS, f"landmark_spawn in {LANDMARK_SPAWNS}, got {sc.landmark_spawn!r}")
    need(sc.kind == "particle" or sc.landmark_spawn == "whole", "landmark_spawn 'whole' for drone scenarios")
    for r in ("agent_radius", "landmark_radius", "obstacle_radius"):
        need(getattr(sc, r) > 0, f"{r} > 0, got {getattr(sc, r)}")
    if sc.collision_radius is not None:
        need(sc.kind == "drone", "collision_radius only for drone scenarios (particle agents collide at agent_radius)")
        need(0 < sc.collision_radius < math.inf, f"collision_radius > 0, got {sc.collision_radius}")
    if sc.team_after is not None:
        need(1 <= sc.team_after <= sc.num_agents,
             f"1 <= team_after <= num_agents ({sc.num_agents}), got {sc.team_after}")
        need(1 <= sc.change_step < sc.horizon, f"1 <= change_step < horizon, got {sc.change_step}")
    # Loose packing check so rejection sampling of spawns terminates quickly.
    body_area = math.pi * (sc.num_agents * (sc.agent_radius + 0.05) ** 2
                           + sc.num_obstacles * (sc.obstacle_radius + 0.05) ** 2
                           + sc.num_agents * sc.landmark_radius ** 2)
    need(body_area < 0.35 * sc.area,
         f"a map large enough to place every body without overlap (world_size={sc.world_size:g} "
         f"is too small for {sc.num_agents} agents and {sc.num_obstacles} obstacles)")
