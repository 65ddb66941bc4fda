"""How much of drone-20's failure is the crash shape? The same episodes with a flat frame instead of a sphere.

Usage (from the repository root)::

    python -m experiments.drone_frame --methods masp h-orca --episodes 32 [--half-height 0.03]

The drone world counts a crash when a drone's collision *sphere* (radius 0.27 m = arm + rotor, around a
frame 5 cm tall) touches anything. ``experiments.drone_crashes`` found that MASP's drones fail by grazing:
pairs at exactly the spheres' contact distance, 10 of 12 more than 0.1 m apart in height, where the flat
frames themselves would pass. The paper's drones (OmniDrones) collide with their frame's own shape. This
evaluates methods on the same validation episodes twice: with the product's spheres, and with a flat
cylinder of the same radius (``--half-height`` above and below the rotor plane, default 0.03 m: the hub and
the rotor disks) as each drone's collision shape. Only the crash test changes: spawns, goals, dynamics and
the policies are the product's. A cylinder pair can report more than one contact point, so the collision
*rate* of the frame rows over-counts; SR and Steps are exact.

The evaluation seed is a validation seed (12345): nothing here is chosen on the reported seeds 0–2.
"""
from __future__ import annotations

import argparse

import masp_lite.envs.drone_model as drone_model
from masp_lite.evaluation import evaluate


def flat_frames(half_height: float):
    """Make drone worlds built from now on use a flat cylinder (radius ``COLLISION_RADIUS``, half-height
    ``half_height``) as each drone's collision shape instead of the sphere; returns the undo."""
    true = drone_model.build_xml
    r = drone_model.COLLISION_RADIUS
    sphere = f'type="sphere" size="{r}"'

    def frames(num_drones: int) -> str:
        xml = true(num_drones)
        if xml.count(sphere) != num_drones:
            raise RuntimeError(f"drone_frame: expected one hull {sphere!r} per drone in the drone model")
        return xml.replace(sphere, f'type="cylinder" size="{r} {half_height}"')

    drone_model.build_xml = frames   # read by build_model when a world is built

    def undo():
        drone_model.build_xml = true
    return undo


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.drone_frame", description=__doc__.split("\n")[0])
    p.add_argument("--methods", nargs="+", default=["masp", "h-orca"])
    p.add_argument("--scenario", default="drone-20", choices=["drone-5", "drone-20"],
                   help="MASP flies the shipped weights of this preset")
    p.add_argument("--episodes", type=int, default=32)
    p.add_argument("--seed", type=int, default=12345, help="validation evaluation seed (default 12345)")
    p.add_argument("--half-height", type=float, default=0.03, help="the frame's half-height, metres")
    args = p.parse_args(argv)
    for shape in ("sphere", "frame"):
        undo = flat_frames(args.half_height) if shape == "frame" else (lambda: None)
        try:
            for m in args.methods:
                rec = evaluate(m, args.scenario, episodes=args.episodes, seeds=[args.seed])
                print(f"{shape:6s} {m:10s} SR {rec['sr']['mean']:.3f}  Steps {rec['steps']['mean']:6.1f}  "
                      f"CR {rec['cr']['mean']:.4f}", flush=True)
        finally:
            undo()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
