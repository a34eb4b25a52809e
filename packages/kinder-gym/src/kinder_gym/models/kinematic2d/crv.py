"""Controllers and collision checking for the Kinematic2D "CRV" vacuum robot.

The robot's action is ``[dx, dy, dtheta, darm, vacuum]`` with per-step bounds. A
:class:`CRVController` follows a list of :class:`Waypoint` s: each step moves straight towards the
current waypoint by ``delta / n`` with ``n`` the fewest steps that respect every bound (angles the
short way round), holding the waypoint's vacuum setting; a waypoint counts as reached when the
robot is there. The follower is closed-loop (it reads the observed state), and fails fast with
:class:`~kinder_gym.skills.SkillFailure` when a step does not move the robot (the env reverted a
colliding step).

:class:`CRVCollisionChecker` answers "is the robot (with what it holds) collision-free at this
pose?" for motion planning, with the env's own geometry kernels and z-order rules; extra obstacles
(e.g. buttons the robot must not touch) can be added. :func:`hand_predicates` builds the
suction hand's ``HandEmpty``/``Holding`` predicates every Kinematic2D model shares.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, Type
from kinder_garden2d.geometry import (
    circle_circle_overlap,
    obb_circle_overlap,
    obb_obb_overlap,
    wrap_angle,
)
from kinder_garden2d.kinematic2d.crv import Bodies, KinematicWorld, robot_geometry
from kinder_garden2d.kinematic2d.object_types import CRV_ROBOT, ZOrder
from kinder_gym.concepts import Predicate
from kinder_gym.motion_planning import FloatArray, interpolate_path, plan_se2
from kinder_gym.skills import Controller, SkillFailure

#: Indices of the robot's features in its feature vector.
X, Y, THETA, BASE_RADIUS, ARM_JOINT, ARM_LENGTH, VACUUM, GRIPPER_HEIGHT, GRIPPER_WIDTH = range(9)


@dataclass(frozen=True)
class Waypoint:
    """A target robot configuration (metres, metres, radians, metres) and the vacuum setting
    (0 off, 1 on) held while moving there."""

    x: float
    y: float
    theta: float
    arm: float
    vacuum: float

    def as_array(self) -> FloatArray:
        """``[x, y, theta, arm]``."""
        return np.array([self.x, self.y, self.theta, self.arm])


def robot_config(state: ObjectCentricState, robot: Object) -> FloatArray:
    """``[x, y, theta, arm_joint]`` of the robot."""
    v = state[robot]
    return np.array([v[X], v[Y], v[THETA], v[ARM_JOINT]])


def checked_waypoints(
    checker: CRVCollisionChecker,
    configs: Sequence[FloatArray],
    max_step: FloatArray,
    vacuum: float,
    failure: str,
) -> list[Waypoint]:
    """Waypoints through ``configs`` (``[x, y, theta, arm]``, the first being where the robot
    starts), after checking every pose the follower will step through (the env checks collisions
    at the end of each step; so do we). A collision raises ``SkillFailure("<failure> at q")``."""
    for q in interpolate_path(list(configs), max_step, wrap_dims=(2,))[1:]:
        if not checker(q):
            raise SkillFailure(f"{failure} at {q.round(3)}")
    return [
        Waypoint(float(q[0]), float(q[1]), float(q[2]), float(q[3]), vacuum) for q in configs[1:]
    ]


def config_delta4(a: FloatArray, b: FloatArray) -> FloatArray:
    """``b − a`` for ``[x, y, theta, arm]`` with the angle taken the short way round."""
    d = b - a
    d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
    return d


def check_not_blocked(
    controller: Controller, q: FloatArray, last: FloatArray | None, moved: bool
) -> None:
    """Raise :class:`~kinder_gym.skills.SkillFailure` when the last action moved the robot from
    ``last`` and it is still there at ``q``: the env reverted a colliding step."""
    if moved and last is not None and np.allclose(q, last, atol=1e-12, rtol=0.0):
        raise SkillFailure(f"{type(controller).__name__}: the robot is blocked at {q.round(3)}")


def step_towards(d: FloatArray, max_step: FloatArray) -> FloatArray:
    """One action's ``[dx, dy, dtheta, darm]`` along the configuration change ``d``: ``d``
    split into the fewest equal steps within the per-step bounds ``max_step``."""
    n = max(1, math.ceil(float(np.max(np.abs(d) / max_step)) - 1e-9))
    out: FloatArray = d / n
    return out


class CRVController(Controller):
    """Waypoint following for the CRV robot (see the module docstring).

    The context is the env (its ``action_space`` gives the per-step bounds). Subclasses implement
    :meth:`waypoints`, called once from :meth:`reset`; the first of ``objects`` is the robot.
    """

    #: Distance (metres / radians) under which a waypoint counts as reached.
    tolerance = 1e-6
    #: The vacuum setting of the final (motionless) action; None: the last waypoint's setting
    #: (or the current one when there are no waypoints).
    vacuum_after: float | None = None

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        high = np.asarray(self.context.action_space.high, dtype=np.float64)
        self._max = high[:4]
        self._plan = list(self.waypoints(state))
        self._k = 0
        self._last_config: FloatArray | None = None
        self._last_moved = False
        if self.vacuum_after is not None:
            self._final_vacuum = self.vacuum_after
        elif self._plan:
            self._final_vacuum = self._plan[-1].vacuum
        else:
            self._final_vacuum = float(state[self.robot][VACUUM])

    @property
    def robot(self) -> Object:
        """The robot object."""
        return self.objects[0]

    @abc.abstractmethod
    def waypoints(self, state: ObjectCentricState) -> list[Waypoint]:
        """The waypoints to follow from ``state`` (raise SkillFailure if there are none)."""

    def step(self) -> FloatArray:
        assert self.state is not None
        q = robot_config(self.state, self.robot)
        check_not_blocked(self, q, self._last_config, self._last_moved)
        while self._k < len(self._plan):
            wp = self._plan[self._k]
            d = config_delta4(q, wp.as_array())
            if np.max(np.abs(d)) > self.tolerance:
                self._last_config, self._last_moved = q, True
                return np.array([*step_towards(d, self._max), wp.vacuum])
            self._k += 1
        # Every waypoint reached: one last action that sets the final vacuum without moving.
        self._k += 1
        self._last_config, self._last_moved = q, False
        return np.array([0.0, 0.0, 0.0, 0.0, self._final_vacuum])

    def terminated(self) -> bool:
        return self._k > len(self._plan)


class CRVCollisionChecker:
    """Is the robot (and what it holds) collision-free at a configuration of this state?

    The obstacles (every other object, the env's constant bodies and ``extra``) are fixed when
    the checker is made, and grouped by which z-orders they may collide with, so one query is a
    few vectorized overlap tests (the env's kernels, z-order rules and closed-set semantics).

    Args:
        world: The env's kinematic world (geometry of its objects and constants).
        state: The state whose other objects are the obstacles.
        ignore: Objects that are not obstacles.
        extra: Additional obstacle bodies (e.g. circles around buttons to avoid).
        check_held: Whether held objects are carried along and checked (else ignored).
    """

    def __init__(
        self,
        world: KinematicWorld,
        state: ObjectCentricState,
        ignore: Sequence[Object] = (),
        extra: Bodies | None = None,
        check_held: bool = True,
    ) -> None:
        self.world = world
        self.data: FloatArray = state.data.copy()
        self.robot_vec: FloatArray = self.data[world.robot_idx].copy()
        #: The arm joint used for configurations given as ``[x, y, theta]``.
        self.arm = float(self.robot_vec[ARM_JOINT])
        held = world.suctioned(self.data)
        self.held = held
        bodies = world.object_bodies(self.data)
        skip = set(held.tolist()) | {world.index[o] for o in ignore if o in world.index}
        rmask = ~np.isin(bodies.rowner, list(skip))
        cmask = ~np.isin(bodies.cowner, list(skip))
        parts = [bodies.select(rmask, cmask), world.constants]
        if extra is not None:
            parts.append(extra)
        self.obstacles = Bodies.concat(parts)
        # Held bodies in the tool-tip frame (tip position, robot heading): centre offsets and
        # angle offsets of boxes, centre offsets of circles.
        g = robot_geometry(self.robot_vec)
        th = float(self.robot_vec[THETA])
        tip = np.array(g.tool_tip)
        hr = np.isin(bodies.rowner, held) if check_held else np.zeros(len(bodies.rowner), bool)
        hc = np.isin(bodies.cowner, held) if check_held else np.zeros(len(bodies.cowner), bool)
        self._held_boxes = bodies.obbs[hr].copy()
        self._held_box_z = bodies.rz[hr].copy()
        self._held_circles = bodies.circles[hc].copy()
        self._held_circle_z = bodies.cz[hc].copy()
        self._hb_rel = _to_frame(self._held_boxes[:, :2], tip, th)
        self._hb_ang = np.arctan2(self._held_boxes[:, 3], self._held_boxes[:, 2]) - th
        self._hc_rel = _to_frame(self._held_circles[:, :2], tip, th)
        self._pose_idx = world.pose_idx[held]
        poses = self.data[self._pose_idx]
        self._rel_xy = _to_frame(poses[:, :2], tip, th)
        self._rel_th = poses[:, 2] - th
        # Broad phase: the obstacles' axis-aligned bounding boxes against a circle around the
        # base centre that covers every moving body.
        o = self.obstacles
        ex = np.abs(o.obbs[:, 2]) * o.obbs[:, 4] + np.abs(o.obbs[:, 3]) * o.obbs[:, 5]
        ey = np.abs(o.obbs[:, 3]) * o.obbs[:, 4] + np.abs(o.obbs[:, 2]) * o.obbs[:, 5]
        cx = np.concatenate([o.obbs[:, 0], o.circles[:, 0]])
        cy = np.concatenate([o.obbs[:, 1], o.circles[:, 1]])
        self._ex = np.concatenate([ex, o.circles[:, 2]])
        self._ey = np.concatenate([ey, o.circles[:, 2]])
        self._cx, self._cy = cx, cy
        self._nb = len(o.obbs)
        held_r = 0.0
        if len(self._held_boxes):
            held_r = max(
                held_r,
                float(
                    np.max(
                        np.hypot(self._hb_rel[:, 0], self._hb_rel[:, 1])
                        + np.hypot(self._held_boxes[:, 4], self._held_boxes[:, 5])
                    )
                ),
            )
        if len(self._held_circles):
            held_r = max(
                held_r,
                float(
                    np.max(
                        np.hypot(self._hc_rel[:, 0], self._hc_rel[:, 1]) + self._held_circles[:, 2]
                    )
                ),
            )
        self._held_r = held_r
        self._group_masks: dict[float, tuple[NDArray[np.bool_], NDArray[np.bool_]]] = {}
        self.checks = 0

    def _masks(self, z: float) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """Which obstacle boxes and circles a moving body of layer ``z`` may collide with."""
        got = self._group_masks.get(z)
        if got is None:
            o = self.obstacles

            def hits(oz: FloatArray) -> NDArray[np.bool_]:
                out: NDArray[np.bool_] = ((oz == z) | (oz == ZOrder.ALL) | (z == ZOrder.ALL)) & (
                    oz != ZOrder.NONE
                )
                return out

            got = (hits(o.rz), hits(o.cz))
            self._group_masks[z] = got
        return got

    def _collides(
        self,
        z: float,
        boxes: FloatArray,
        circles: FloatArray,
        near_b: NDArray[np.bool_],
        near_c: NDArray[np.bool_],
    ) -> bool:
        if z == ZOrder.NONE:
            return False
        mb, mc = self._masks(z)
        ob = self.obstacles.obbs[near_b & mb]
        oc = self.obstacles.circles[near_c & mc]
        if len(boxes):
            if len(ob) and obb_obb_overlap(boxes, ob).any():
                return True
            if len(oc) and obb_circle_overlap(boxes, oc).any():
                return True
        if len(circles):
            if len(ob) and obb_circle_overlap(ob, circles).any():
                return True
            if len(oc) and circle_circle_overlap(circles, oc).any():
                return True
        return False

    def robot_vector(self, config: Sequence[float] | FloatArray) -> FloatArray:
        """The robot's features with its pose (and arm joint, if given) set to ``config``."""
        vec = self.robot_vec.copy()
        vec[X], vec[Y], vec[THETA] = config[0], config[1], config[2]
        vec[ARM_JOINT] = config[3] if len(config) > 3 else self.arm
        out: FloatArray = vec
        return out

    def data_at(self, config: Sequence[float] | FloatArray) -> FloatArray:
        """The state's data with the robot at ``config`` (``[x, y, theta]`` or with the arm
        joint as a fourth entry) and held objects carried along."""
        data: FloatArray = self.data.copy()
        vec = self.robot_vector(config)
        data[self.world.robot_idx] = vec
        if self.held.size:
            tip = np.array(robot_geometry(vec).tool_tip)
            th = float(vec[THETA])
            data[self._pose_idx] = np.column_stack(
                [_from_frame(self._rel_xy, tip, th), wrap_angle(self._rel_th + th)]
            )
        return data

    def __call__(self, config: Sequence[float] | FloatArray) -> bool:
        """True when nothing the robot moves collides at ``config``."""
        self.checks += 1
        x, y, th = float(config[0]), float(config[1]), float(config[2])
        v = self.robot_vec
        aj = float(config[3]) if len(config) > 3 else self.arm
        br, gh, gw = float(v[BASE_RADIUS]), float(v[GRIPPER_HEIGHT]), float(v[GRIPPER_WIDTH])
        reach = max(br, math.hypot(aj + 0.5 * gw, 0.5 * gh))
        if self._held_r > 0.0:
            reach = max(reach, aj + 0.5 * gw + self._held_r)
        near = (np.abs(self._cx - x) <= self._ex + reach) & (
            np.abs(self._cy - y) <= self._ey + reach
        )
        if not near.any():
            return True
        nb, nc = near[: self._nb], near[self._nb :]
        c, s = math.cos(th), math.sin(th)
        base = np.array([[x, y, br]])
        arm_grip = np.array(
            [
                [x + 0.5 * aj * c, y + 0.5 * aj * s, c, s, 0.5 * aj, 0.25 * gw],
                [x + aj * c, y + aj * s, c, s, 0.5 * gw, 0.5 * gh],
            ]
        )
        if self._collides(ZOrder.ALL, _NO_BOXES, base, nb, nc):
            return False
        if self._collides(ZOrder.SURFACE, arm_grip, _NO_CIRCLES, nb, nc):
            return False
        if self.held.size:
            tip = np.array([x + (aj + 0.5 * gw) * c, y + (aj + 0.5 * gw) * s])
            boxes = self._held_boxes.copy()
            boxes[:, :2] = _from_frame(self._hb_rel, tip, th)
            ang = self._hb_ang + th
            boxes[:, 2], boxes[:, 3] = np.cos(ang), np.sin(ang)
            circles = self._held_circles.copy()
            circles[:, :2] = _from_frame(self._hc_rel, tip, th)
            for z in np.unique(np.concatenate([self._held_box_z, self._held_circle_z])):
                if self._collides(
                    float(z),
                    boxes[self._held_box_z == z],
                    circles[self._held_circle_z == z],
                    nb,
                    nc,
                ):
                    return False
        return True


_NO_BOXES = np.zeros((0, 6))
_NO_CIRCLES = np.zeros((0, 3))


def _to_frame(points: FloatArray, origin: FloatArray, theta: float) -> FloatArray:
    """World points in the frame at ``origin`` rotated by ``theta``."""
    c, s = math.cos(theta), math.sin(theta)
    d = points - origin
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def _from_frame(points: FloatArray, origin: FloatArray, theta: float) -> FloatArray:
    """Points of the frame at ``origin`` rotated by ``theta``, in world coordinates."""
    c, s = math.cos(theta), math.sin(theta)
    return np.column_stack(
        [
            origin[0] + c * points[:, 0] - s * points[:, 1],
            origin[1] + s * points[:, 0] + c * points[:, 1],
        ]
    )


def circle_obstacles(circles: FloatArray, z: int = ZOrder.ALL) -> Bodies:
    """Static circle obstacles ``[[cx, cy, r], ...]`` that collide with every robot body."""
    c = np.asarray(circles, dtype=np.float64).reshape(-1, 3)
    return Bodies.of(circles=c, circle_z=[z] * len(c), static=False)


def plan_base_path(
    checker: CRVCollisionChecker,
    start: FloatArray,
    goal: FloatArray,
    bounds: tuple[tuple[float, float], tuple[float, float]],
    seed: int,
    timeout: float = 2.0,
) -> list[FloatArray]:
    """A collision-free SE(2) path for the base (arm fixed), or SkillFailure."""
    path = plan_se2(
        start[:3],
        goal[:3],
        checker,
        bounds,
        max_step=(0.01, 0.01, math.pi / 64),
        seed=seed,
        timeout=timeout,
    )
    if path is None:
        raise SkillFailure(f"no collision-free base path from {start.round(3)} to {goal.round(3)}")
    return path


def world_sampling_bounds(
    env: ObjectCentricEnv, margin: float
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The env's world box shrunk by ``margin`` (metres), for sampling base poses."""
    xmin, xmax, ymin, ymax = env.config.world_bounds  # type: ignore[attr-defined]
    return (xmin + margin, xmax - margin), (ymin + margin, ymax - margin)


def checked_base_waypoints(
    checker: CRVCollisionChecker,
    path: Sequence[FloatArray],
    arm: float,
    env: ObjectCentricEnv,
    vacuum: float,
) -> list[Waypoint]:
    """Waypoints along a base path, after checking every pose the follower will step through
    (the env checks collisions only at the end of each step)."""
    high = np.asarray(env.action_space.high, dtype=np.float64)[:3]
    for q in interpolate_path(path, high, wrap_dims=(2,))[1:]:
        if not checker(q):
            raise SkillFailure(f"an execution step of the path collides at {q.round(3)}")
    return [Waypoint(float(q[0]), float(q[1]), float(q[2]), arm, vacuum) for q in path[1:]]


def held_objects(env: ObjectCentricEnv, state: ObjectCentricState) -> list[Object]:
    """The objects the robot's suction holds in ``state`` (the env's world decides)."""
    return env.world.held_objects(state.data)  # type: ignore[attr-defined, no-any-return]


def hand_predicates(
    env: ObjectCentricEnv, held: Type, holding_name: str = "Holding"
) -> tuple[Predicate, Predicate]:
    """``HandEmpty(robot)`` (the suction holds nothing) and ``holding_name(robot, held)`` (it
    holds that object), the hand's predicates of the Kinematic2D models."""
    hand_empty = Predicate("HandEmpty", (CRV_ROBOT,), lambda s, o: not held_objects(env, s))
    holding = Predicate(holding_name, (CRV_ROBOT, held), lambda s, o: o[1] in held_objects(env, s))
    return hand_empty, holding
