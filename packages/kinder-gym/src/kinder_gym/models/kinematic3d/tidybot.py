"""Controllers, IK and collision checking for the Kinematic3D mobile manipulator.

The robot's configuration is 10-D: base ``(x, y, yaw)`` and 7 arm joints (joints 1, 3, 5 and 7
are continuous and wrap); its action adds bounded deltas to it and ends with a gripper command
(< −0.5 close, > 0.5 open). A :class:`TidyBotController` follows 10-D waypoints closed-loop (one
straight step of ``delta / n`` at a time, ``n`` the fewest steps within the bounds, wrapped
dimensions the short way round) and may end each waypoint with a gripper command. It fails fast
with :class:`~kinder_gym.skills.SkillFailure` when a motion step does not move the robot (the env
reverted a colliding motion).

:class:`ConfigChecker` tells whether a configuration is collision-free in a state, with the env's
own pybullet geometry (``env.penetrations``), carrying the held object (and what a held container
holds) along. Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.geometry import compose, invert, normalize_quat, quat_to_matrix
from kinder_garden3d.kinematic3d.scene import TOOL_OFFSET
from kinder_garden3d.robot.description import PINCH_OFFSET, RETRACT, robot_description
from kinder_garden3d.robot.ik import InverseKinematics
from kinder_gym.motion_planning import FloatArray, plan_joint_space, plan_se2
from kinder_gym.skills import Controller, SkillFailure

_LOW, _HIGH = robot_description().arm_joint_limits
#: Which of the 10 configuration dimensions wrap (base yaw and the continuous joints).
WRAP_DIMS: tuple[int, ...] = (2, *(3 + i for i in range(7) if not np.isfinite(_LOW[i])))
JOINT_LOW = np.where(np.isfinite(_LOW), _LOW, -math.pi)
JOINT_HIGH = np.where(np.isfinite(_HIGH), _HIGH, math.pi)
HOME = np.array(RETRACT, dtype=np.float64)


def wrap(theta: float) -> float:
    """An angle wrapped to [−π, π)."""
    return (theta + math.pi) % (2 * math.pi) - math.pi


def config_delta(a: FloatArray, b: FloatArray) -> FloatArray:
    """``b − a`` over the 10-D configuration (or the 7 arm joints), wrapped dimensions the
    short way round."""
    d = np.asarray(b, dtype=np.float64) - np.asarray(a, dtype=np.float64)
    offset = 0 if len(d) == 10 else 3
    for i in WRAP_DIMS:
        if 0 <= i - offset < len(d):
            d[i - offset] = wrap(float(d[i - offset]))
    return d


def top_down_quat(yaw: float) -> FloatArray:
    """The end-effector orientation (x, y, z, w) pointing straight down, turned by ``yaw`` about
    the world z axis (the fingers then close along the direction ``yaw + π/2``)."""
    c, s = math.cos(yaw / 2), math.sin(yaw / 2)
    # Rz(yaw) ⊗ Ry(π): (0, 0, s, c) ⊗ (0, 1, 0, 0).
    return np.array([-s, c, 0.0, 0.0])


#: A quarter turn about z (x, y, z, w): the gripper (pinch) frame in the tool frame.
_TOOL_TO_GRIPPER = np.array([0.0, 0.0, -math.sqrt(0.5), math.sqrt(0.5)])


def tool_to_pinch(pos: FloatArray, quat: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The pinch-point pose (what :func:`solve_ik` places) of a tool-frame pose (the env's
    ``ee_pose`` and the frame of the grasp-transform features): the pinch point lies
    ``PINCH_OFFSET − TOOL_OFFSET`` further along the approach axis, and the gripper frame is
    the tool frame turned a quarter about that axis."""
    p = np.asarray(pos, dtype=np.float64)
    q = np.asarray(quat, dtype=np.float64)
    pinch_p = p + quat_to_matrix(q)[:, 2] * (PINCH_OFFSET - TOOL_OFFSET)
    _, pinch_q = compose(np.zeros(3), q, np.zeros(3), _TOOL_TO_GRIPPER)
    return pinch_p, normalize_quat(pinch_q)


@dataclass(frozen=True)
class ConfigWaypoint:
    """A 10-D configuration to reach, and an optional gripper command sent once there
    (−1 close, +1 open, 0 none)."""

    config: tuple[float, ...]
    gripper: float = 0.0


class TidyBotController(Controller):
    """Waypoint following for the Kinematic3D robot (see the module docstring).

    The context is the env. Subclasses implement :meth:`waypoints`; the first object is the
    robot.
    """

    tolerance = 1e-7

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        self._max = np.asarray(self.context.action_space.high, dtype=np.float64)[:10]
        self._plan = list(self.waypoints(state))
        self._k = 0
        self._gripper_sent = False
        self._last: FloatArray | None = None

    @property
    def robot(self) -> Object:
        """The robot object."""
        return self.objects[0]

    @abc.abstractmethod
    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        """The waypoints from ``state`` (raise SkillFailure when there are none)."""

    def step(self) -> FloatArray:
        assert self.state is not None
        q = np.asarray(self.state[self.robot][:10], dtype=np.float64)
        if self._last is not None and np.allclose(q, self._last, atol=1e-12, rtol=0.0):
            raise SkillFailure(f"{type(self).__name__}: the robot is blocked")
        while self._k < len(self._plan):
            wp = self._plan[self._k]
            d = config_delta(q, np.array(wp.config))
            if np.max(np.abs(d)) > self.tolerance:
                n = max(1, math.ceil(float(np.max(np.abs(d) / self._max)) - 1e-9))
                self._last = q
                return np.array([*(d / n), 0.0])
            if wp.gripper != 0.0 and not self._gripper_sent:
                self._gripper_sent = True
                self._last = None
                return np.array([*np.zeros(10), wp.gripper])
            self._k += 1
            self._gripper_sent = False
        self._last = None
        return np.zeros(11)

    def terminated(self) -> bool:
        if self.state is None:
            return False
        q = np.asarray(self.state[self.robot][:10], dtype=np.float64)
        k, sent = self._k, self._gripper_sent
        while k < len(self._plan):
            wp = self._plan[k]
            if np.max(np.abs(config_delta(q, np.array(wp.config)))) > self.tolerance:
                return False
            if wp.gripper != 0.0 and not sent:
                return False
            k, sent = k + 1, False
        return True


class ConfigChecker:
    """Collision-free test of robot configurations in a state (see the module docstring)."""

    def __init__(self, env: ObjectCentricEnv, state: ObjectCentricState) -> None:
        self.env = env
        self.state = state.copy()
        self.robot = env.robot  # type: ignore[attr-defined]
        self.held = env.held_object(state)  # type: ignore[attr-defined]
        self.carried = env.contents(state, self.held)  # type: ignore[attr-defined]
        tf = state[self.robot][12:19]
        self.grasp_tf = (np.asarray(tf[:3]), np.asarray(tf[3:]))
        moving = {"robot"}
        if self.held is not None:
            moving |= {self.held.name, *(o.name for o in self.carried)}
        self.moving = moving
        self._base_pose = {
            o: (state[o][:3].copy(), state[o][3:7].copy())
            for o in [self.held, *self.carried]
            if o is not None
        }
        self.checks = 0
        self._self_collision: dict[tuple[float, ...], bool] = {}

    def state_at(self, config: Sequence[float] | FloatArray) -> ObjectCentricState:
        """The state with the robot at ``config`` (held objects carried along)."""
        s = self.state.copy()
        s[self.robot][:10] = np.asarray(config, dtype=np.float64)
        if self.held is not None:
            ee_p, ee_q = self.env.ee_pose(s)  # type: ignore[attr-defined]
            new_p, new_q = compose(ee_p, ee_q, *self.grasp_tf)
            old_p, old_q = self._base_pose[self.held]
            s[self.held][:3], s[self.held][3:7] = new_p, normalize_quat(new_q)
            dp, dq = compose(new_p, new_q, *invert(old_p, old_q))
            for o in self.carried:
                p, q = compose(dp, dq, *self._base_pose[o])
                s[o][:3], s[o][3:7] = p, normalize_quat(q)
        return s

    def __call__(self, config: Sequence[float] | FloatArray) -> bool:
        self.checks += 1
        state = self.state_at(config)
        if self.env.config.check_self_collisions:  # type: ignore[attr-defined]
            # Self-collision depends on the arm alone: base motions reuse one verdict.
            arm = tuple(float(v) for v in np.asarray(config)[3:10])
            if arm not in self._self_collision:
                self._self_collision[arm] = bool(self.env.self_collision(state))  # type: ignore[attr-defined]
            if self._self_collision[arm]:
                return False
        pairs = self.env.penetrations(state)  # type: ignore[attr-defined]
        # Only contacts between something that moves and something that does not count.
        return all((a in self.moving) == (b in self.moving) for a, b in pairs)


def arm_path(
    checker: ConfigChecker,
    start: FloatArray,
    goal_arm: FloatArray,
    seed: int,
    timeout: float = 2.0,
) -> list[FloatArray]:
    """A collision-free path of the arm (base fixed) to ``goal_arm``, as 10-D configurations."""
    base = np.asarray(start[:3], dtype=np.float64)

    def valid(q: FloatArray) -> bool:
        return checker(np.concatenate([base, q]))

    # Continuous joints are planned without wrapping: bring the goal next to the start.
    goal = np.asarray(goal_arm, dtype=np.float64).copy()
    for i in WRAP_DIMS[1:]:
        j = i - 3
        goal[j] = start[i] + wrap(float(goal[j] - start[i]))
    lo = np.minimum(JOINT_LOW, np.minimum(start[3:], goal) - 0.5)
    hi = np.maximum(JOINT_HIGH, np.maximum(start[3:], goal) + 0.5)
    path = plan_joint_space(
        start[3:],
        goal,
        valid,
        lo,
        hi,
        max_step=0.1,
        seed=seed,
        timeout=timeout,
        max_iterations=3000,
    )
    if path is None:
        raise SkillFailure("no collision-free arm path")
    return [np.concatenate([base, q]) for q in path[1:]]


def base_path(
    checker: ConfigChecker,
    start: FloatArray,
    goal_base: FloatArray,
    bounds: tuple[float, float, float, float],
    seed: int,
    timeout: float = 2.0,
) -> list[FloatArray]:
    """A collision-free base path (arm fixed), as 10-D configurations."""
    arm = np.asarray(start[3:10], dtype=np.float64)

    def valid(q: FloatArray) -> bool:
        return checker(np.concatenate([q, arm]))

    x0, x1, y0, y1 = bounds
    path = plan_se2(
        start[:3],
        goal_base,
        valid,
        ((x0, x1), (y0, y1)),
        max_step=(0.05, 0.05, 0.1),
        seed=seed,
        timeout=timeout,
        max_iterations=3000,
    )
    if path is None:
        raise SkillFailure("no collision-free base path")
    return [np.concatenate([q, arm]) for q in path[1:]]


_IK: InverseKinematics | None = None


def solve_ik(
    position: FloatArray, quat: FloatArray, base: FloatArray, init: FloatArray
) -> FloatArray:
    """Arm joints putting the end effector at the pose (base fixed), or SkillFailure."""
    global _IK
    if _IK is None:
        _IK = InverseKinematics(free_base=False)
    result = _IK.solve(
        position,
        quat,
        base_pose=(float(base[0]), float(base[1]), float(base[2])),
        initial_arm_joints=init,
        restarts=2,
    )
    if not result.success:
        raise SkillFailure(f"no IK solution for the end effector at {np.round(position, 3)}")
    return np.asarray(result.arm_joints, dtype=np.float64)
