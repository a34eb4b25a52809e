"""Inverse kinematics for the end effector (``pinch_site``), built on mink and the generated MJCF.

Two modes share one API:

* ``InverseKinematics(free_base=False)`` moves only the 7 arm joints; the base pose is given and
  the target is expressed in the world frame.
* ``InverseKinematics(free_base=True)`` also moves the planar base (x, y, yaw).

Targets are a position and a quaternion ordered (x, y, z, w), as in the Kinematic3D features. The
solver is differential IK (mink's QP with joint limits) with a small posture regulariser, restarted
from deterministic random seeds when it stalls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mink
import mujoco
import numpy as np
from numpy.typing import NDArray

from kinder_garden3d.robot.description import (
    RobotDescription,
    quat_xyzw_to_matrix,
    robot_description,
)
from kinder_garden3d.robot.mjcf import to_mjcf

_SITE = "pinch_site"


@dataclass(frozen=True)
class IKResult:
    """Outcome of an IK query.

    ``arm_joints`` has 7 entries; ``base_pose`` is (x, y, yaw). ``position_error`` (m) and
    ``orientation_error`` (rad) are measured at the returned configuration.
    """

    success: bool
    arm_joints: NDArray[np.float64]
    base_pose: tuple[float, float, float]
    position_error: float
    orientation_error: float


class InverseKinematics:
    """End-effector IK for the mobile manipulator (see module docstring)."""

    def __init__(self, free_base: bool = False, desc: RobotDescription | None = None) -> None:
        """``desc`` is the robot (default: the mobile manipulator; e.g. the FR3 arm of
        :func:`~kinder_garden3d.robot.fr3.fr3_description`); its ``retract`` is the first guess."""
        self.free_base = free_base
        desc = robot_description() if desc is None else desc
        self._retract = desc.retract
        self._model = mujoco.MjModel.from_xml_string(to_mjcf(desc, free_base=free_base))
        self._config = mink.Configuration(self._model)
        self._task = mink.FrameTask(_SITE, "site", position_cost=1.0, orientation_cost=1.0)
        self._posture = mink.PostureTask(self._model, cost=1e-3)
        self._limits: list[mink.Limit] = [mink.ConfigurationLimit(self._model)]
        self._arm_qadr = np.array(
            [self._model.jnt_qposadr[self._model.joint(n).id] for n in desc.arm_joint_names]
        )
        self._finger_qadr = np.array(
            [self._model.jnt_qposadr[self._model.joint(n).id] for n in desc.finger_joint_names]
        )
        self._base_qadr = (
            np.array(
                [self._model.jnt_qposadr[self._model.joint(n).id] for n in desc.base_joint_names]
            )
            if free_base
            else np.zeros(0, dtype=int)
        )
        self._arm_lower, self._arm_upper = desc.arm_joint_limits

    def solve(
        self,
        target_position: NDArray[np.float64] | tuple[float, float, float],
        target_quat_xyzw: NDArray[np.float64] | tuple[float, float, float, float],
        base_pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
        initial_arm_joints: NDArray[np.float64] | tuple[float, ...] | None = None,
        base_z: float = 0.0,
        position_tolerance: float = 1e-4,
        orientation_tolerance: float = 1e-3,
        max_iterations: int = 300,
        restarts: int = 8,
        seed: int = 0,
    ) -> IKResult:
        """Solve for a configuration putting ``pinch_site`` at the target pose.

        ``base_pose`` is the fixed base pose (fixed-base mode) or the initial guess (free-base
        mode); ``base_z`` is the height of the base frame in the world.
        """
        pos = np.asarray(target_position, dtype=float)
        quat = np.asarray(target_quat_xyzw, dtype=float)
        if pos.shape != (3,):
            raise ValueError(f"target_position must have shape (3,), got {pos.shape}")
        if quat.shape != (4,) or not np.isclose(np.linalg.norm(quat), 1.0, atol=1e-6):
            raise ValueError(f"target_quat_xyzw must be a unit quaternion (x, y, z, w), got {quat}")
        if len(base_pose) != 3:
            raise ValueError(f"base_pose must be (x, y, yaw), got {base_pose}")
        rot = quat_xyzw_to_matrix(quat)
        bx, by, byaw = (float(v) for v in base_pose)
        if self.free_base:
            local_pos, local_rot = pos - np.array([0.0, 0.0, base_z]), rot
        else:
            c, s = math.cos(byaw), math.sin(byaw)
            rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            local_pos = rz.T @ (pos - np.array([bx, by, base_z]))
            local_rot = rz.T @ rot
        target = mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(local_rot), local_pos)
        self._task.set_target(target)

        arm0 = np.array(
            self._retract if initial_arm_joints is None else initial_arm_joints, dtype=float
        )
        if arm0.shape != (7,):
            raise ValueError(f"initial_arm_joints must have 7 entries, got {arm0.shape}")
        rng = np.random.default_rng(seed)
        best: IKResult | None = None
        for attempt in range(restarts + 1):
            q = np.zeros(self._model.nq)
            if attempt == 0:
                q[self._arm_qadr] = np.clip(arm0, self._arm_lower, self._arm_upper)
            else:
                low = np.where(np.isfinite(self._arm_lower), self._arm_lower, -math.pi)
                high = np.where(np.isfinite(self._arm_upper), self._arm_upper, math.pi)
                q[self._arm_qadr] = rng.uniform(low, high)
            if self.free_base:
                q[self._base_qadr] = (bx, by, byaw)
            result = self._iterate(q, position_tolerance, orientation_tolerance, max_iterations)
            if best is None or (result.position_error + result.orientation_error) < (
                best.position_error + best.orientation_error
            ):
                best = result
            if result.success:
                break
        assert best is not None
        if not self.free_base:
            best = IKResult(
                best.success,
                best.arm_joints,
                (bx, by, byaw),
                best.position_error,
                best.orientation_error,
            )
        return best

    def _iterate(
        self, q0: NDArray[np.float64], pos_tol: float, rot_tol: float, max_iterations: int
    ) -> IKResult:
        config = self._config
        config.update(q0)
        self._posture.set_target(q0.copy())
        dt = 0.5
        pos_err = rot_err = math.inf
        for _ in range(max_iterations):
            err = self._task.compute_error(config)
            pos_err, rot_err = float(np.linalg.norm(err[:3])), float(np.linalg.norm(err[3:]))
            if pos_err < pos_tol and rot_err < rot_tol:
                break
            vel = mink.solve_ik(
                config, [self._task, self._posture], dt, "daqp", damping=1e-4, limits=self._limits
            )
            config.integrate_inplace(vel, dt)
        err = self._task.compute_error(config)
        pos_err, rot_err = float(np.linalg.norm(err[:3])), float(np.linalg.norm(err[3:]))
        q = config.q.copy()
        arm = q[self._arm_qadr].copy()
        # Wrap continuous joints into [-pi, pi).
        continuous = ~np.isfinite(self._arm_lower)
        arm[continuous] = (arm[continuous] + math.pi) % (2.0 * math.pi) - math.pi
        if self.free_base:
            x, y, yaw = (float(v) for v in q[self._base_qadr])
            base = (x, y, (yaw + math.pi) % (2.0 * math.pi) - math.pi)
        else:
            base = (0.0, 0.0, 0.0)
        return IKResult(pos_err < pos_tol and rot_err < rot_tol, arm, base, pos_err, rot_err)
