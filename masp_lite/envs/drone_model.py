"""The Hummingbird quadrotor as a MuJoCo model, built in code (MJCF text).

No quadrotor model ships with the ``mujoco`` wheel (``mujoco-menagerie`` downloads its
files at run time), so this module writes one. The constants are those of the AscTec
Hummingbird as OmniDrones configures it (the paper's drone testbed, section
"Experiments — OmniDrones"):

=========================  =====================================================
mass                       0.716 kg
inertia                    Ixx = Iyy = 0.007, Izz = 0.012 kg·m²
arms                       0.17 m, "+" layout: rotors at 0°, 90°, 180°, −90°
spin directions            −1, +1, −1, +1
force constant kf          8.54858e-6 N/(rad/s)²
moment constant km         1.36777e-7 N·m/(rad/s)²
max rotor speed            838 rad/s → max thrust kf·ω² ≈ 6.0 N per rotor
rotor lag                  throttle += 0.43 · (target − throttle) per 0.016 s
=========================  =====================================================

Rotor model (OmniDrones' ``RotorGroup``): a command ``c ∈ [−1, 1]`` asks for the
throttle ``sqrt((c + 1) / 2)``; the throttle follows it with the first-order lag above;
rotor ``i`` then pushes ``f_i = throttle² · f_max`` along the body z axis at its arm tip
and twists the body about z by ``−d_i · (km / kf) · f_i`` (``d_i`` its spin direction).
In steady state the thrust is linear in the command: ``f = (c + 1) / 2 · f_max``; hover
is ``c ≈ −0.41`` (29 % of the maximum thrust). The lag lives in the world (it is applied
once per control step, as in OmniDrones); MuJoCo receives each rotor's thrust as the
control of a ``general`` actuator on a site at the arm tip whose ``gear`` carries the
force along z and the reaction torque.

Geometry. Drone ``i`` is a free body ``drone{i}``: a hub, four arms and four rotor disks
(visual only, rotor radius ``ROTOR_RADIUS`` = 0.1 m, the 8-inch propellers) and one
collision sphere of radius ``COLLISION_RADIUS`` = arm + rotor = 0.27 m that encloses it
all. The floor is a plane at z = 0. Landmarks are drawn by the viewers, not simulated:
they are virtual balls (paper: radius 0.05 m) that nothing touches.

Contacts are reported by two MuJoCo ``contact`` sensors per drone (``data="found"``): the
contacts of the drone's sphere with anything, and with the floor. With spheres each
touching pair yields exactly one contact, so the drone–drone pairs are half the sum of the
differences (see :mod:`masp_lite.envs.drones`).

The model can be saved and opened in MuJoCo's viewer::

    python -c "from masp_lite.envs.drone_model import save_xml; save_xml('drones.xml', 5)"
    python -m mujoco.viewer --mjcf=drones.xml
"""
from __future__ import annotations

import math

import mujoco
import numpy as np
import torch

from ..files import atomic_write

__all__ = ["DRONE_SPEED", "HUMMINGBIRD", "ARM_LENGTH", "ROTOR_RADIUS", "COLLISION_RADIUS", "CONTROL_DT",
           "PHYSICS_DT", "SUBSTEPS", "MAX_THRUST", "HOVER_COMMAND", "build_xml", "build_model",
           "save_xml", "rotor_positions", "GRAVITY", "quat_to_matrix"]

#: The Hummingbird's constants (OmniDrones ``hummingbird.yaml``).
HUMMINGBIRD = dict(
    mass=0.716, inertia=(0.007, 0.007, 0.012), arm_length=0.17,
    rotor_angles=(0.0, math.pi / 2, math.pi, -math.pi / 2), directions=(-1.0, 1.0, -1.0, 1.0),
    force_constant=8.54858e-6, moment_constant=1.36777e-7, max_rotor_speed=838.0,
    rotor_lag=0.43,
)
ARM_LENGTH = HUMMINGBIRD["arm_length"]
ROTOR_RADIUS = 0.1
COLLISION_RADIUS = ARM_LENGTH + ROTOR_RADIUS
GRAVITY = 9.81
CONTROL_DT = 0.016
"""Seconds per environment step (OmniDrones' simulation step)."""
SUBSTEPS = 4
"""MuJoCo steps per environment step."""
PHYSICS_DT = CONTROL_DT / SUBSTEPS
MAX_THRUST = HUMMINGBIRD["force_constant"] * HUMMINGBIRD["max_rotor_speed"] ** 2
"""Thrust of one rotor at full throttle, N (≈ 6.0)."""
DRONE_SPEED = 4.0
"""m/s: the drones' speed scale. Networks divide velocities by it, and a ``velocity`` action of 1
asks for it (:func:`masp_lite.planners.geometric.motor_commands`)."""
HOVER_COMMAND = 2 * HUMMINGBIRD["mass"] * GRAVITY / (4 * MAX_THRUST) - 1
"""Command that holds every rotor at a quarter of the weight in steady state (≈ −0.41)."""


def rotor_positions() -> np.ndarray:
    """(4, 2) rotor x, y in the body frame, from the arm length and the "+" layout angles."""
    a = np.asarray(HUMMINGBIRD["rotor_angles"])
    return ARM_LENGTH * np.stack([np.cos(a), np.sin(a)], axis=1)


def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:
    """Rotation matrices (..., 3, 3) from unit quaternions (..., 4) in MuJoCo's (w, x, y, z)."""
    w, x, y, z = q.unbind(-1)
    return torch.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1).reshape(*q.shape[:-1], 3, 3)


def _drone(i: int, collision_radius: float) -> str:
    h = HUMMINGBIRD
    ixx, iyy, izz = h["inertia"]
    yaw_ratio = h["moment_constant"] / h["force_constant"]
    rotors, arms = [], []
    for k, ((x, y), d) in enumerate(zip(rotor_positions(), h["directions"])):
        colour = "0.9 0.3 0.2 0.6" if d < 0 else "0.2 0.5 0.9 0.6"
        arms.append(f'<geom class="visual" type="capsule" size="0.01" fromto="0 0 0 {x:.6f} {y:.6f} 0"/>')
        rotors.append(
            f'<geom class="visual" type="cylinder" size="{ROTOR_RADIUS} 0.004" pos="{x:.6f} {y:.6f} 0.02" '
            f'rgba="{colour}"/>'
            f'<site name="d{i}_rotor{k}" pos="{x:.6f} {y:.6f} 0.02" size="0.01"/>')
    return (
        f'<body name="drone{i}" pos="{2 * i * collision_radius:.3f} 0 1">'
        f'<freejoint name="d{i}_joint"/>'
        f'<inertial pos="0 0 0" mass="{h["mass"]}" diaginertia="{ixx} {iyy} {izz}"/>'
        f'<geom name="d{i}_hull" type="sphere" size="{collision_radius}" rgba="0 0 0 0" group="3"/>'
        f'<geom class="visual" type="box" size="0.05 0.05 0.025" rgba="0.25 0.25 0.3 1"/>'
        + "".join(arms) + "".join(rotors) + "</body>"
    ), "".join(
        f'<general name="d{i}_motor{k}" site="d{i}_rotor{k}" ctrlrange="0 {MAX_THRUST:.6f}" '
        f'gear="0 0 1 0 0 {-d * yaw_ratio:.8f}"/>'
        for k, d in enumerate(h["directions"])
    ), (
        f'<contact name="d{i}_any" subtree1="drone{i}" data="found" reduce="mindist"/>'
        f'<contact name="d{i}_floor" subtree1="drone{i}" geom2="floor" data="found" reduce="mindist"/>'
    )


def build_xml(num_drones: int, collision_radius: float = COLLISION_RADIUS) -> str:
    """MJCF text of ``num_drones`` Hummingbirds over a floor (see the module docstring), each in a
    collision sphere of ``collision_radius`` (a scenario may set another,
    :attr:`~masp_lite.envs.scenarios.Scenario.collision_radius`)."""
    if not isinstance(num_drones, (int, np.integer)) or num_drones < 1:
        raise ValueError(f"num_drones: expected a positive int, got {num_drones!r}")
    parts = [_drone(i, collision_radius) for i in range(int(num_drones))]
    return f"""<mujoco model="hummingbirds">
  <option timestep="{PHYSICS_DT}" gravity="0 0 -{GRAVITY}" integrator="implicitfast"/>
  <default>
    <default class="visual"><geom contype="0" conaffinity="0" group="1" rgba="0.3 0.3 0.35 1"/></default>
  </default>
  <visual><global offwidth="640" offheight="480"/></visual>
  <worldbody>
    <light pos="0 0 10" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" size="0 0 0.05" rgba="0.85 0.85 0.85 1"/>
    {''.join(p[0] for p in parts)}
  </worldbody>
  <actuator>{''.join(p[1] for p in parts)}</actuator>
  <sensor>{''.join(p[2] for p in parts)}</sensor>
</mujoco>"""


def build_model(num_drones: int, collision_radius: float = COLLISION_RADIUS) -> mujoco.MjModel:
    """Compile :func:`build_xml` into an ``MjModel``."""
    return mujoco.MjModel.from_xml_string(build_xml(num_drones, collision_radius))


def save_xml(path: str, num_drones: int = 5) -> str:
    """Write the model of ``num_drones`` drones to ``path`` (open it in ``mujoco.viewer``)."""
    atomic_write(path, build_xml(num_drones))
    return path
