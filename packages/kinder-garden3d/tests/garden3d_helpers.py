"""Helpers for the Kinematic3D tests: put the gripper at a pose with IK, build actions."""

from __future__ import annotations

from functools import cache

import numpy as np

from kinder_core import ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import Kinematic3DEnv
from kinder_garden3d.robot.ik import InverseKinematics

#: Gripper pointing straight down (rotation of pi about x): approach = −z, closing axis = −y.
DOWN = (1.0, 0.0, 0.0, 0.0)


@cache
def _ik() -> InverseKinematics:
    return InverseKinematics(free_base=False)


def arm_for(env: Kinematic3DEnv, state: ObjectCentricState, ee_pos: np.ndarray) -> np.ndarray:
    """Arm joints putting the end effector at ``ee_pos`` pointing down, base as in ``state``."""
    robot = state[env.robot]
    result = _ik().solve(
        np.asarray(ee_pos, dtype=float),
        DOWN,
        base_pose=(float(robot[0]), float(robot[1]), float(robot[2])),
        initial_arm_joints=robot[3:10],
        base_z=env.config.base_z,
    )
    assert result.success, f"IK failed for {ee_pos}: {result.position_error}"
    return result.arm_joints


def with_arm_at(
    env: Kinematic3DEnv, state: ObjectCentricState, ee_pos: np.ndarray
) -> ObjectCentricState:
    """A copy of ``state`` with the end effector at ``ee_pos`` (pointing down)."""
    out = state.copy()
    out[env.robot][3:10] = arm_for(env, state, ee_pos)
    return out


def action(
    base: tuple[float, float, float] = (0.0, 0.0, 0.0),
    joints: np.ndarray | None = None,
    gripper: float = 0.0,
) -> np.ndarray:
    """An 11-D action."""
    a = np.zeros(11)
    a[:3] = base
    if joints is not None:
        a[3:10] = joints
    a[10] = gripper
    return a


CLOSE = action(gripper=-1.0)
OPEN = action(gripper=1.0)


def move_ee(
    env: Kinematic3DEnv,
    state: ObjectCentricState,
    ee_pos: np.ndarray,
    cartesian_step: float = 0.05,
) -> ObjectCentricState:
    """Step the env (from ``state``) so the end effector moves in a straight line to ``ee_pos``.

    The line is cut into waypoints ``cartesian_step`` apart; each is solved with IK from the
    previous joints (intermediate waypoints the arm cannot reach are skipped) and reached with
    joint deltas within the action bound.
    """
    env.set_state(state)
    start, _ = env.pinch_pose(state)
    goal = np.asarray(ee_pos, dtype=float)
    n_way = max(1, int(np.ceil(np.linalg.norm(goal - start) / cartesian_step)))
    bound = env.config.max_action_mag
    for k in range(1, n_way + 1):
        waypoint = start + (goal - start) * k / n_way
        if k < n_way:
            robot = state[env.robot]
            result = _ik().solve(
                waypoint,
                DOWN,
                base_pose=(float(robot[0]), float(robot[1]), float(robot[2])),
                initial_arm_joints=robot[3:10],
                base_z=env.config.base_z,
                restarts=0,
            )
            if not result.success:  # skip waypoints the arm cannot reach pointing down
                continue
            target = result.arm_joints
        else:
            target = arm_for(env, state, waypoint)
        delta = (target - state[env.robot][3:10] + np.pi) % (2 * np.pi) - np.pi
        n = max(1, int(np.ceil(np.max(np.abs(delta)) / bound)))
        for _ in range(n):
            state, *_ = env.step(action(joints=delta / n))
    return state
