"""Flying the Hummingbirds: motor mixing and a Lee geometric controller.

Why hand-written: the controller is a dozen lines of linear algebra on batched torch
tensors (B worlds × N drones at once); no CPU library ships a batched one. It follows
Lee, Leok & McClamroch, "Geometric tracking control of a quadrotor UAV on SE(3)"
(CDC 2010), as OmniDrones' ``LeePositionController`` uses it, with the Hummingbird's gains
from OmniDrones (position 4, velocity 2.2, attitude [0.7, 0.7, 0.035], rate
[0.1, 0.1, 0.025]):

1. **position loop** — desired acceleration ``a = −k_x e_x − k_v e_v + g e_3 + a_d``
   (:func:`position_loop`); ``e_x`` is clipped so that the cruise speed stays below
   ``max_speed`` (a saturated P-loop: ``k_x |e_x| = k_v v_max`` at cruise);
2. **attitude** — the body z axis must point along ``a``; with the yaw heading
   ``b_1c = (cos ψ, sin ψ, 0)``: ``b_3 = a/|a|``, ``b_2 = b_3 × b_1c / |·|``,
   ``b_1 = b_2 × b_3``, ``R_d = [b_1 b_2 b_3]``;
3. **collective thrust** ``f = m a · R e_3`` and **moments**
   ``M = −k_R e_R − k_Ω Ω + Ω × JΩ`` with ``e_R = ½ (R_dᵀR − RᵀR_d)^∨``;
4. **motor mixing** — the rotor thrusts ``f_i`` solve ``A f = (f, M_x, M_y, M_z)``, where
   ``A`` (:func:`allocation_matrix`) follows from the rotor layout: rotor ``i`` at
   ``(x_i, y_i)`` adds ``y_i f_i`` to the roll moment, ``−x_i f_i`` to the pitch moment and
   ``−d_i (k_m/k_f) f_i`` to the yaw moment; ``MIXER = A⁻¹``;
5. **commands** ``c_i = 2 f_i / f_max − 1`` (the inverse of the rotor model's steady state,
   :mod:`masp_lite.envs.drone_model`), clipped to [−1, 1].

The drones' ``h-greedy`` flies with it: :class:`masp_lite.policies.drones.DroneHungarianGreedy`.
"""
from __future__ import annotations

import numpy as np
import torch

from ..envs.drone_model import DRONE_SPEED, GRAVITY, HUMMINGBIRD, MAX_THRUST, quat_to_matrix

__all__ = ["motor_commands", "velocity_controller", "allocation_matrix", "mixing_matrix", "MIXER", "quat_to_matrix",
           "position_loop", "LeeController",
           "thrusts_to_commands"]


def allocation_matrix(arm_length: float = HUMMINGBIRD["arm_length"],
                      rotor_angles=HUMMINGBIRD["rotor_angles"], directions=HUMMINGBIRD["directions"],
                      yaw_ratio: float = HUMMINGBIRD["moment_constant"] / HUMMINGBIRD["force_constant"]
                      ) -> np.ndarray:
    """(4, 4) map from rotor thrusts to (collective thrust, roll, pitch, yaw moment).

    Rotor ``i`` sits at ``arm_length · (cos a_i, sin a_i)`` and spins in direction ``d_i``;
    the defaults are the Hummingbird's "+" layout.
    """
    a = np.asarray(rotor_angles, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    if a.shape != (4,) or d.shape != (4,):
        raise ValueError(f"rotor_angles and directions: expected 4 values each, got {a.shape} and {d.shape}")
    x, y = arm_length * np.cos(a), arm_length * np.sin(a)
    return np.stack([np.ones(4), y, -x, -d * yaw_ratio])


def mixing_matrix(arm_length: float = HUMMINGBIRD["arm_length"], rotor_angles=HUMMINGBIRD["rotor_angles"],
                  directions=HUMMINGBIRD["directions"],
                  yaw_ratio: float = HUMMINGBIRD["moment_constant"] / HUMMINGBIRD["force_constant"]) -> np.ndarray:
    """(4, 4) motor mixing, the inverse of :func:`allocation_matrix`: wrench → rotor thrusts."""
    return np.linalg.inv(allocation_matrix(arm_length, rotor_angles, directions, yaw_ratio))


MIXER = mixing_matrix()
"""(4, 4) motor mixing of the Hummingbird: rotor thrusts = MIXER @ (thrust, M_x, M_y, M_z)."""


def position_loop(pos, vel, target_pos, target_vel, target_acc, kx: float = 4.0, kv: float = 2.2,
                  max_speed: float | None = None) -> torch.Tensor:
    """Desired acceleration (..., 3) of Lee's position loop, gravity compensated.

    ``a = −kx·e_x − kv·e_v + g·e_3 + a_d`` with ``e_x = pos − target_pos`` (its norm clipped
    to ``kv/kx · max_speed`` when ``max_speed`` is given) and ``e_v = vel − target_vel``.
    """
    ex = pos - target_pos
    if max_speed is not None:
        norm = ex.norm(dim=-1, keepdim=True).clamp_min(1e-9)
        ex = ex * (kv * max_speed / kx / norm).clamp(max=1.0)
    g = torch.zeros_like(pos)
    g[..., 2] = GRAVITY
    return -kx * ex - kv * (vel - target_vel) + g + target_acc


def thrusts_to_commands(thrusts: torch.Tensor) -> torch.Tensor:
    """Motor commands in [−1, 1] whose steady-state thrust is ``thrusts`` (clipped)."""
    return (2 * thrusts / MAX_THRUST - 1).clamp(-1.0, 1.0)


class LeeController:
    """Batched geometric controller: drone states and targets → motor commands (..., 4).

    Call it with the world's observation tensors: ``pos``, ``vel`` (world frame),
    ``quat`` (w x y z), ``angvel`` (body frame) and optional ``target_pos`` (default: hold
    the current position), ``target_vel``, ``target_acc`` (default 0), ``target_yaw``
    (default 0 rad). ``position_loop`` may replace :func:`position_loop` (same signature),
    e.g. by a learner's own version in the course.
    """

    def __init__(self, kx: float = 4.0, kv: float = 2.2, k_att=(0.7, 0.7, 0.035),
                 k_rate=(0.1, 0.1, 0.025), max_speed: float | None = None, max_tilt_acc: float = 8.0,
                 position_loop=None):
        self.position_loop = globals()["position_loop"] if position_loop is None else position_loop
        if not callable(self.position_loop):
            raise ValueError(f"position_loop: expected a function, got {type(position_loop).__name__}")
        for name, v in (("kx", kx), ("kv", kv), ("max_tilt_acc", max_tilt_acc)):
            if not (isinstance(v, (int, float)) and v > 0):
                raise ValueError(f"{name}: expected a positive number, got {v!r}")
        if max_speed is not None and not (isinstance(max_speed, (int, float)) and max_speed > 0):
            raise ValueError(f"max_speed: expected a positive number or None, got {max_speed!r}")
        self.kx, self.kv, self.max_speed, self.max_tilt_acc = float(kx), float(kv), max_speed, float(max_tilt_acc)
        self.k_att = torch.tensor(k_att, dtype=torch.float64)
        self.k_rate = torch.tensor(k_rate, dtype=torch.float64)
        self.inertia = torch.tensor(HUMMINGBIRD["inertia"], dtype=torch.float64)
        self.mixer = torch.from_numpy(MIXER)

    def __call__(self, pos, vel, quat, angvel, target_pos=None, target_vel=None, target_acc=None,
                 target_yaw=None) -> torch.Tensor:
        dtype = pos.dtype
        pos, vel, quat, angvel = (x.to(torch.float64) for x in (pos, vel, quat, angvel))
        zero = torch.zeros_like(pos)
        tp = pos if target_pos is None else target_pos.to(torch.float64)
        tv = zero if target_vel is None else target_vel.to(torch.float64)
        ta = zero if target_acc is None else target_acc.to(torch.float64)
        acc = self.position_loop(pos, vel, tp, tv, ta, self.kx, self.kv, self.max_speed)
        # limit the horizontal part (the tilt), never the vertical one
        h = acc[..., :2].norm(dim=-1, keepdim=True).clamp_min(1e-9)
        acc = torch.cat([acc[..., :2] * (self.max_tilt_acc / h).clamp(max=1.0), acc[..., 2:].clamp_min(0.5)], -1)
        R = quat_to_matrix(quat / quat.norm(dim=-1, keepdim=True))
        yaw = torch.zeros(pos.shape[:-1], dtype=torch.float64) if target_yaw is None else \
            torch.as_tensor(target_yaw, dtype=torch.float64).expand(pos.shape[:-1])
        b1c = torch.stack([yaw.cos(), yaw.sin(), torch.zeros_like(yaw)], -1)
        b3 = acc / acc.norm(dim=-1, keepdim=True)
        b2 = torch.linalg.cross(b3, b1c)
        b2 = b2 / b2.norm(dim=-1, keepdim=True).clamp_min(1e-9)
        Rd = torch.stack([torch.linalg.cross(b2, b3), b2, b3], -1)
        E = 0.5 * (Rd.transpose(-1, -2) @ R - R.transpose(-1, -2) @ Rd)
        e_R = torch.stack([E[..., 2, 1], E[..., 0, 2], E[..., 1, 0]], -1)
        moments = -self.k_att * e_R - self.k_rate * angvel + torch.linalg.cross(angvel, self.inertia * angvel)
        thrust = HUMMINGBIRD["mass"] * (acc * R[..., :, 2]).sum(-1, keepdim=True)
        rotor = torch.cat([thrust, moments], -1) @ self.mixer.T
        return thrusts_to_commands(rotor).to(dtype)


def velocity_controller() -> LeeController:
    """The geometric controller that flies ``velocity`` actions (velocity gain 4, speed capped at ``DRONE_SPEED``)."""
    return LeeController(kv=4.0, max_speed=DRONE_SPEED)


def motor_commands(actions: torch.Tensor, obs: dict, controller: LeeController | None = None) -> torch.Tensor:
    """The world's motor commands (B, N, 4) for MASP's drone executor's actions, clipped to [−1, 1] first.

    Without ``controller`` (``action="throttle"``) the clipped actions are the commands; with one
    (``action="velocity"``, :func:`velocity_controller`) the clipped action × ``DRONE_SPEED`` is the
    velocity set-point the controller flies from the drone's own position. The drone policy and the
    drone trainer both act through it.
    """
    a = actions.clamp(-1.0, 1.0)
    if controller is None:
        return a
    pos = obs["agent_pos"]
    return controller(pos, obs["agent_vel"], obs["agent_quat"], obs["agent_angvel"], target_pos=pos,
                      target_vel=a * DRONE_SPEED)
