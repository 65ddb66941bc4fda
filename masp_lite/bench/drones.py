"""``bench drones``: the drone world's throughput against raw MuJoCo on the same model.

Measures :class:`~masp_lite.envs.drones.DroneWorld` on ``drone-20`` for 1 and 16 parallel
worlds, and, *in the same run*, plain ``mujoco.mj_step`` on the world's own ``MjModel``
and start state (``DroneWorld.get_data``, a copy): ``SUBSTEPS`` calls per environment
step, one ``MjData`` per world, the same motor thrusts. (The world steps one world with
``mj_step`` on its own ``MjData`` too, and several with ``mujoco.batch``.) The ratio
``raw rate / world rate`` is the world's overhead: everything it adds to the physics
(action checks, the rotor lag, contact sensors recorded per substep, crash and coverage
bookkeeping, torch observations). The target is ≤ 1.5×.

Workload: every drone hovers at the hover command (no crash, so every drone stays in the
physics for the whole measurement and both sides simulate the same thing). A world that
reaches its horizon is reset inside the timed loop. The two sides are timed in alternating
short rounds (``--rounds``, sharing ``--seconds`` of wall time each) and each keeps its best
round, so that a load change on a shared machine hits both alike. ``--threads`` is the
``mujoco.batch`` thread count (default 1, to compare with the single-threaded raw loop).

Options: ``--seconds``, ``--rounds``, ``--worlds``, ``--threads``, ``--json PATH``.
"""
from __future__ import annotations

import argparse

import mujoco
import torch

from ..envs.drone_model import HOVER_COMMAND, SUBSTEPS
from ..envs.drones import DroneWorld
from . import calls_per_second, write_json
from .competing import warn_if_busy

SCENARIO = "drone-20"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=4.0, help="wall time per side and batch size (default 4)")
    parser.add_argument("--rounds", type=int, default=5, help="alternating rounds per side (default 5)")
    parser.add_argument("--worlds", type=int, nargs="+", default=[1, 16], help="batch sizes (default 1 16)")
    parser.add_argument("--threads", type=int, default=1, help="mujoco.batch threads (default 1)")
    parser.add_argument("--json", metavar="PATH", default=None, help="also write the results as JSON")


def measure(num_envs: int, seconds: float, threads: int = 1, rounds: int = 5, seed: int = 0) -> dict:
    """Env-steps/s of the world and of raw ``mj_step`` for ``num_envs`` drone-20 worlds."""
    world = DroneWorld(SCENARIO, num_envs=num_envs, seed=seed, threads=threads)
    actions = torch.full((num_envs, world.num_agents, 4), HOVER_COMMAND)

    def world_step():
        world.step(actions)
        if bool(world.done.any()):
            world.reset()

    datas = [world.get_data(i) for i in range(num_envs)]
    model = world.model
    for d in datas:
        d.ctrl[:] = world._ctrl[0]
        mujoco.mj_forward(model, d)

    def raw_step():
        for d in datas:
            for _ in range(SUBSTEPS):
                mujoco.mj_step(model, d)

    world_rate = raw_rate = 0.0
    for _ in range(rounds):
        world_rate = max(world_rate, calls_per_second(world_step, seconds / rounds) * num_envs)
        raw_rate = max(raw_rate, calls_per_second(raw_step, seconds / rounds) * num_envs)
    return {"worlds": num_envs, "env_steps_per_s": world_rate, "agent_steps_per_s": world_rate * world.num_agents,
            "raw_env_steps_per_s": raw_rate, "overhead": raw_rate / world_rate}


def run(args: argparse.Namespace) -> int:
    if args.seconds <= 0 or args.rounds < 1 or any(b < 1 for b in args.worlds) or args.threads < 0:
        raise ValueError("bench drones: expected --seconds > 0, --rounds >= 1, --worlds >= 1 and --threads >= 0")
    torch.set_num_threads(1)
    warn_if_busy()
    print(f"{SCENARIO}: {SUBSTEPS} MuJoCo steps per env step, hovering; raw = mj_step on the same model")
    print(f"{'worlds':>6} {'env-steps/s':>12} {'agent-steps/s':>14} {'raw mj env-steps/s':>19} {'overhead':>9}")
    rows = []
    for b in args.worlds:
        r = measure(b, args.seconds, args.threads, args.rounds)
        rows.append(r)
        print(f"{b:>6} {r['env_steps_per_s']:>12.0f} {r['agent_steps_per_s']:>14.0f} "
              f"{r['raw_env_steps_per_s']:>19.0f} {r['overhead']:>8.2f}x")
    worst = max(r["overhead"] for r in rows)
    print(f"overhead vs raw mj_step: worst {worst:.2f}x (target <= 1.5x)")
    if args.json:
        write_json(args.json, {"scenario": SCENARIO, "substeps": SUBSTEPS, "threads": args.threads, "results": rows})
    return 0
