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
holds) along. :class:`ReachController` (retract, drive to a standoff, reach a pre-pose above the
target or along any approach, move in, act, back out or lift), :class:`PickController` (its pick,
with a per-family grasp hook) and :class:`TableTopController` (reach from the home base pose) are
the motions the family models build their skills from (:func:`release_pose` aims a held object,
:func:`bounds_around` lets the base pass a family's furniture); :func:`hand_predicates`,
:func:`hand_atoms` and :func:`held_or_resting` build the hand's predicates and atoms every family
model shares (its pick/place operators come from :mod:`kinder_gym.models.hand`).
Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, Type
from kinder_garden3d.kinematic3d.base_env import CONTAINER_MIN_HALF_EXTENT
from kinder_garden3d.kinematic3d.geometry import (
    compose,
    invert,
    normalize_quat,
    quat_to_matrix,
    yaw_quat,
)
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE, ROBOT_TYPE
from kinder_garden3d.kinematic3d.scene import TOOL_OFFSET
from kinder_garden3d.robot.description import PINCH_OFFSET, RETRACT, robot_description
from kinder_garden3d.robot.ik import InverseKinematics
from kinder_gym.concepts import GroundAtom, Predicate
from kinder_gym.motion_planning import (
    FloatArray,
    params_seed,
    plan_joint_space,
    plan_se2,
    segment_valid,
)
from kinder_gym.skills import Controller, SkillFailure

_LOW, _HIGH = robot_description().arm_joint_limits
#: Which of the 10 configuration dimensions wrap (base yaw and the continuous joints).
WRAP_DIMS: tuple[int, ...] = (2, *(3 + i for i in range(7) if not np.isfinite(_LOW[i])))
JOINT_LOW = np.where(np.isfinite(_LOW), _LOW, -math.pi)
JOINT_HIGH = np.where(np.isfinite(_HIGH), _HIGH, math.pi)
HOME = np.array(RETRACT, dtype=np.float64)


def _chassis_half_xy() -> tuple[float, float]:
    """Half extents (x, y) of the base link's colliding boxes, in the base frame."""
    base = robot_description().links[0]
    boxes = [g for g in base.geoms if g.collide and g.kind == "box"]
    return (
        max(abs(g.pos[0]) + g.size[0] for g in boxes),
        max(abs(g.pos[1]) + g.size[1] for g in boxes),
    )


#: The base chassis's footprint (half extents along the base's x and y, metres).
CHASSIS_HALF_XY = _chassis_half_xy()
#: A family's env config type (see :meth:`TidyBotController.env_config`).
ConfigT = TypeVar("ConfigT")


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


def release_pose(
    state: ObjectCentricState, robot: Object, spot: FloatArray, tool_quat: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The pinch pose (what :func:`solve_ik` places) that puts the held object's centre at
    ``spot`` with the tool frame turned to ``tool_quat``: the object hangs off the tool frame
    by the robot's grasp transform (its features 12–14), so the tool goes to ``spot`` less
    that offset turned into the world frame."""
    tf_p = np.asarray(state[robot][12:15], dtype=np.float64)
    tool_p = np.asarray(spot, dtype=np.float64) - quat_to_matrix(tool_quat) @ tf_p
    return tool_to_pinch(tool_p, tool_quat)


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

    def env_config(self, kind: type[ConfigT]) -> ConfigT:
        """The env's config, checked to be a ``kind`` (a family's controllers need its env)."""
        cfg = self.context.config
        if not isinstance(cfg, kind):
            env_name = kind.__name__.removesuffix("Config")
            raise TypeError(f"{type(self).__name__} needs a {env_name} env, got {cfg!r}")
        return cfg

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
        #: Objects whose contacts with the robot are not collisions while they lie within the
        #: base chassis's footprint (where only the chassis can touch them; for envs that do
        #: not check the base, see :meth:`ReachController.make_checker`).
        self.under_base: frozenset[str] = frozenset()
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
        # Only contacts between something that moves and something that does not count: the env
        # checks just those pairs. The robot may touch what lies under its base.
        pairs = self.env.penetrations(state, self.moving)  # type: ignore[attr-defined]
        return all(
            (a == "robot" and self._under_base(state, b))
            or (b == "robot" and self._under_base(state, a))
            for a, b in pairs
        )

    def _under_base(self, state: ObjectCentricState, name: str) -> bool:
        """Whether ``name`` is in :attr:`under_base` and its footprint (a disc of its half
        extents' radius) meets the chassis's footprint at the robot's base pose."""
        if name not in self.under_base:
            return False
        f = state[state.get_object_from_name(name)]
        x, y, yaw = (float(v) for v in state[self.robot][:3])
        dx, dy = float(f[0]) - x, float(f[1]) - y
        c, s = math.cos(yaw), math.sin(yaw)
        lx, ly = c * dx + s * dy, -s * dx + c * dy
        r = float(np.hypot(f[9], f[10]))
        hx, hy = CHASSIS_HALF_XY
        return abs(lx) < hx + r and abs(ly) < hy + r


def _split_turns(base: FloatArray, path: Sequence[FloatArray]) -> list[FloatArray]:
    """The arm ``path`` (7-D, start first) as 10-D configurations after the start, its segments
    split where they turn a continuous joint by more than half a turn.

    The path is checked without wrapping, but the controller turns a continuous joint the
    short way round: split, the arm moves along the checked segment (unsplit, it left it and
    the env stopped it on a collision)."""
    wrapped = [i - 3 for i in WRAP_DIMS[1:]]
    out = []
    prev = np.asarray(path[0], dtype=np.float64)
    for q in path[1:]:
        q = np.asarray(q, dtype=np.float64)
        d = q - prev
        n = max(1, math.ceil(float(np.max(np.abs(d[wrapped]), initial=0.0)) / 3.0))
        out += [np.concatenate([base, prev + d * (k / n)]) for k in range(1, n + 1)]
        prev = q
    return out


#: Collision-checking resolution of arm motions (radians per joint).
ARM_STEP = 0.1


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
    # A limited joint stays within the env's limits (the env clips a motion beyond them, and
    # the arm then stops short of the path).
    limits = checker.env.config.arm_joint_limits  # type: ignore[attr-defined]
    for j, lim in enumerate(limits):
        if lim is not None:
            lo[j] = min(max(lo[j], -lim), start[3 + j], goal[j])
            hi[j] = max(min(hi[j], lim), start[3 + j], goal[j])
    path = plan_joint_space(
        start[3:],
        goal,
        valid,
        lo,
        hi,
        max_step=ARM_STEP,
        seed=seed,
        timeout=timeout,
        max_iterations=3000,
    )
    if path is None:
        raise SkillFailure("no collision-free arm path")
    return _split_turns(base, path)


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


def bounds_around(
    bounds: tuple[float, float, float, float], x: float, y: float
) -> tuple[float, float, float, float]:
    """Planning ``bounds`` (x0, x1, y0, y1) grown to hold the point (x, y) with
    ``PLANNING_MARGIN`` around it (a family's fixed furniture the base must be able to pass)."""
    x0, x1, y0, y1 = bounds
    m = PLANNING_MARGIN
    return min(x0, x - m), max(x1, x + m), min(y0, y - m), max(y1, y + m)


#: Height above the grasp/place pose of the pre-grasp/pre-place end-effector pose (metres).
APPROACH = 0.12
#: How far past the objects (and the robot) the base may be planned to go (metres).
PLANNING_MARGIN = 1.0


#: Gap left under a placed object (the env releases within 5 mm of a surface).
PLACE_GAP = 0.003
#: How far the base backs off from its home pose for objects too close to the arm to reach.
BACK_OFF = 0.15


def yaw_of(q: FloatArray) -> float:
    m = quat_to_matrix(q)
    return math.atan2(float(m[1, 0]), float(m[0, 0]))


class ReachController(TidyBotController):
    """Shared motion pieces: retract, drive, reach down, act, lift."""

    def _wp(self, q: FloatArray, gripper: float = 0.0) -> ConfigWaypoint:
        return ConfigWaypoint(tuple(float(v) for v in q), gripper)

    def _drive(
        self,
        checker: ConfigChecker,
        q: FloatArray,
        base_goal: FloatArray,
        bounds: tuple[float, float, float, float],
        arm_seed: int,
        base_seed: int,
    ) -> tuple[list[ConfigWaypoint], FloatArray]:
        """Retract the arm where the robot stands, then drive the base to ``base_goal`` within
        ``bounds`` (each step only when needed): the waypoints and the configuration reached."""
        wps: list[ConfigWaypoint] = []
        if np.max(np.abs(config_delta(q[3:], HOME))) > 1e-6:
            path = arm_path(checker, q, HOME, arm_seed)
            wps += [self._wp(p) for p in path]
            q = path[-1]
        if np.max(np.abs(config_delta(q[:3], base_goal))) > 1e-6:
            path = base_path(checker, q, base_goal, bounds, base_seed)
            wps += [self._wp(p) for p in path]
            q = path[-1]
        return wps, q

    def _sequence(
        self,
        state: ObjectCentricState,
        base_goal: FloatArray,
        ee_pos: FloatArray,
        ee_quat: FloatArray,
        gripper: float,
        salt: int,
        approach: FloatArray | None = None,
        lift: FloatArray | None = None,
    ) -> list[ConfigWaypoint]:
        """Retract, drive to ``base_goal``, reach the pre-pose ``ee_pos + approach`` (default
        ``APPROACH`` straight above), move straight in, send ``gripper``, then move back to the
        pre-pose, or to ``ee_pos + lift`` when ``lift`` is given."""
        checker = self.make_checker(state)
        q = np.asarray(state[self.robot][:10], dtype=np.float64)
        seed = params_seed(self.params, salt)
        wps, q = self._drive(checker, q, base_goal, self.planning_bounds(state), seed, seed)
        # Reach the pre-pose, then move in (IK seeded from the retract pose, then from the
        # pre-pose).
        offset = np.array([0.0, 0.0, APPROACH]) if approach is None else approach
        above = solve_ik(ee_pos + offset, ee_quat, q[:3], HOME)
        at = solve_ik(ee_pos, ee_quat, q[:3], above)
        q_above = np.concatenate([q[:3], above])
        q_at = np.concatenate([q[:3], at])
        path = arm_path(checker, q, above, seed + 1)
        wps += [self._wp(p) for p in path]
        if not segment_valid(q_above, q_at, checker, np.full(10, 0.05)):
            raise SkillFailure(f"{type(self).__name__}: the final approach collides")
        wps.append(self._wp(q_at, gripper))
        # Move back out (the env checks that move itself).
        if lift is None:
            wps.append(self._wp(q_above))
        else:
            up = solve_ik(ee_pos + lift, ee_quat, q[:3], at)
            wps.append(self._wp(np.concatenate([q[:3], up])))
        return wps

    def make_checker(self, state: ObjectCentricState) -> ConfigChecker:
        """The collision checker of the motions planned from ``state`` (families may let it
        pass over objects, see :attr:`ConfigChecker.under_base`)."""
        return ConfigChecker(self.context, state)

    def planning_bounds(self, state: ObjectCentricState) -> tuple[float, float, float, float]:
        """Where the base may go while planning: the box around the robot and every cuboid,
        grown by ``PLANNING_MARGIN`` and kept within the env's world bounds (which are far
        larger than the scene: ±10 m)."""
        xs = [float(state[o][0]) for o in state if o.type in (ROBOT_TYPE, CUBOID_TYPE)]
        ys = [float(state[o][1]) for o in state if o.type in (ROBOT_TYPE, CUBOID_TYPE)]
        x0, x1, y0, y1 = self.context.config.world_bounds
        m = PLANNING_MARGIN
        return (
            max(x0, min(xs) - m),
            min(x1, max(xs) + m),
            max(y0, min(ys) - m),
            min(y1, max(ys) + m),
        )

    def _standoff(
        self, state: ObjectCentricState, point: FloatArray, dist: float, angle: float
    ) -> FloatArray:
        """A base pose ``dist`` from ``point`` facing it, approaching from direction ``angle``."""
        x, y = point[0] - dist * math.cos(angle), point[1] - dist * math.sin(angle)
        x0, x1, y0, y1 = self.planning_bounds(state)
        if not (x0 < x < x1 and y0 < y < y1):
            raise SkillFailure(f"{type(self).__name__}: standoff ({x:.2f}, {y:.2f}) out of bounds")
        return np.array([x, y, wrap(angle)])


class PickController(ReachController):
    """Pick an object off the floor or the table from a sampled standoff (a container by the top
    of its nearest wall). Objects: ``(robot, object)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(dist, angle): the base stands 0.45 + 0.2·dist metres from the grasp point, approaching "
        "from (angle − 0.5)·π radians off the line from the robot to the object."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.robot, "grasp_active") < 0.5

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, obj = self.objects
        dist = 0.45 + 0.2 * float(self.params[0])
        f = state[obj]
        pos = np.asarray(f[:3], dtype=np.float64)
        base = np.asarray(state[robot][:2], dtype=np.float64)
        offset = (float(self.params[1]) - 0.5) * math.pi
        angle = math.atan2(pos[1] - base[1], pos[0] - base[0]) + offset
        grasp, close_dir, turns = self._grasp(f, angle)
        # Fingers close along ee_yaw + π/2; take the yaw closest to the approach direction.
        candidates = [close_dir - math.pi / 2 + k * math.pi / 2 for k in turns]
        ee_yaw = min(candidates, key=lambda y: abs(wrap(y - angle)))
        base_goal = self._standoff(state, grasp, dist, angle)
        return self._sequence(state, base_goal, grasp, top_down_quat(ee_yaw), -1.0, salt=1)

    def _grasp(self, f: FloatArray, angle: float) -> tuple[FloatArray, float, tuple[int, ...]]:
        """The grasp point of the object with features ``f`` approached from ``angle``, the
        direction the fingers close along, and the quarter turns of that direction they may
        take: across the wall for a container (two), across any pair of faces for a cube
        (four)."""
        pos = np.asarray(f[:3], dtype=np.float64)
        obj_yaw = yaw_of(np.asarray(f[3:7]))
        half = np.asarray(f[9:12], dtype=np.float64)
        # Upstream's object_type is −1 for every cuboid; a container is what the env carries
        # things in (every half extent above CONTAINER_MIN_HALF_EXTENT).
        if not bool(np.all(half > CONTAINER_MIN_HALF_EXTENT)):
            return pos.copy(), obj_yaw, (0, 1, 2, 3)
        # Grasp the top of the wall nearest the robot.
        c, s = math.cos(obj_yaw), math.sin(obj_yaw)
        local = np.array([math.cos(angle + math.pi), math.sin(angle + math.pi)])
        lx, ly = c * local[0] + s * local[1], -s * local[0] + c * local[1]
        if abs(lx) * half[1] >= abs(ly) * half[0]:
            off = np.array([math.copysign(half[0] - 0.005, lx), 0.0])
            close_dir = obj_yaw
        else:
            off = np.array([0.0, math.copysign(half[1] - 0.005, ly)])
            close_dir = obj_yaw + math.pi / 2
        grasp = np.array(
            [
                pos[0] + c * off[0] - s * off[1],
                pos[1] + s * off[0] + c * off[1],
                pos[2] + half[2] - 0.02,
            ]
        )
        return grasp, close_dir, (0, 2)


class TableTopController(ReachController):
    """Reach from a chosen base pose (driving there with the arm retracted when it differs):
    arm path to above a pose, straight descent, act, lift back."""

    def _reach(
        self,
        state: ObjectCentricState,
        base: FloatArray,
        ee_pos: FloatArray,
        ee_quat: FloatArray,
        gripper: float,
        salt: int,
    ) -> list[ConfigWaypoint]:
        env = self.context
        checker = ConfigChecker(env, state)
        q = np.asarray(state[self.robot][:10], dtype=np.float64)
        # The IK model stands on z = 0; these envs sink the base to ``base_z``.
        ee_pos = ee_pos - np.array([0.0, 0.0, float(env.config.base_z)])
        above = solve_ik(ee_pos + np.array([0.0, 0.0, APPROACH]), ee_quat, base, HOME)
        at = solve_ik(ee_pos, ee_quat, base, above)
        q_above = np.concatenate([base, above])
        q_at = np.concatenate([base, at])
        # The cheap endpoint tests first: most infeasible samples fail here.
        if not checker(q_at) or not checker(q_above):
            raise SkillFailure(f"{type(self).__name__}: the grasp/place pose collides")
        if not segment_valid(q_above, q_at, checker, np.full(10, 0.05)):
            raise SkillFailure(f"{type(self).__name__}: the final approach collides")
        seed = params_seed(self.params, salt)
        wps: list[ConfigWaypoint] = []
        if np.max(np.abs(config_delta(q[:3], base))) > 1e-6:
            # Drive with the arm retracted.
            x0, x1, y0, y1 = env.config.world_bounds
            wps, q = self._drive(checker, q, base, (x0, x1, y0, y1), seed + 5, seed + 7)
        path = arm_path(checker, q, above, seed)
        wps += [self._wp(p) for p in path]
        return [*wps, self._wp(q_at, gripper), self._wp(q_above)]

    def _first_feasible(
        self,
        state: ObjectCentricState,
        poses: Sequence[tuple[FloatArray, FloatArray]],
        gripper: float,
        salt: int,
    ) -> list[ConfigWaypoint]:
        """The waypoints of the first end-effector pose that works from the first base pose
        that works (the current one, the home one, then the home one moved back for poses too
        close to the arm); else the last failure."""
        env = self.context
        current = np.asarray(state[self.robot][:3], dtype=np.float64)
        home = np.asarray(env.config.home_base_pose, dtype=np.float64)
        bases = [current]
        for b in (home, home - np.array([BACK_OFF, 0.0, 0.0])):
            if all(np.max(np.abs(b - c)) > 1e-6 for c in bases):
                bases.append(b)
        error = SkillFailure(f"{type(self).__name__}: no candidate pose")
        for i, base in enumerate(bases):
            for k, (pos, quat) in enumerate(poses):
                try:
                    return self._reach(state, base, pos, quat, gripper, salt + 10 * k + 100 * i)
                except SkillFailure as e:
                    error = e
        raise error

    def _place_poses(
        self, state: ObjectCentricState, pos: FloatArray, yaws: Sequence[float]
    ) -> list[tuple[FloatArray, FloatArray]]:
        """End-effector poses putting the held object upright at ``pos`` with each yaw."""
        tf = state[self.robot][12:19]
        inv_p, inv_q = invert(np.asarray(tf[:3]), np.asarray(tf[3:]))
        return [tool_to_pinch(*compose(pos, yaw_quat(y), inv_p, inv_q)) for y in yaws]


def polygons_overlap(a: FloatArray, b: FloatArray, margin: float) -> bool:
    """Whether two convex polygons come closer than ``margin`` on every separating axis."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.column_stack([edges[:, 1], -edges[:, 0]])
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        pa, pb = a @ normals.T, b @ normals.T
        sep = np.maximum(pb.min(axis=0) - pa.max(axis=0), pa.min(axis=0) - pb.max(axis=0))
        if np.any(sep >= margin):
            return False
    return True


def hand_predicates(held: Type = CUBOID_TYPE) -> tuple[Predicate, Predicate]:
    """``HandEmpty(robot)`` and ``Holding(robot, held)``, the hand's predicates of the
    Kinematic3D models (each model's abstraction decides when they hold)."""
    return Predicate("HandEmpty", (ROBOT_TYPE,)), Predicate("Holding", (ROBOT_TYPE, held))


def held_or_resting(
    state: ObjectCentricState,
    robot: Object,
    holding: Predicate,
    objects: Sequence[Object],
    resting: Callable[[ObjectCentricState, Object], GroundAtom],
) -> set[GroundAtom]:
    """``Holding(robot, o)`` for each of ``objects`` the robot holds (its ``grasp_active`` is
    on), and the atom ``resting`` gives for each of the others (where it lies)."""
    return {
        holding.ground([robot, o]) if state.get(o, "grasp_active") > 0.5 else resting(state, o)
        for o in objects
    }


def hand_atoms(state: ObjectCentricState, robot: Object, hand_empty: Predicate) -> set[GroundAtom]:
    """``{HandEmpty(robot)}`` when the robot holds nothing (its grasp is off), else ``{}``."""
    if state.get(robot, "grasp_active") < 0.5:
        return {hand_empty.ground([robot])}
    return set()
