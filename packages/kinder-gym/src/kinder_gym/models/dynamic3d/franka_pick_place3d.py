"""The FrankaPickPlace3D planning model: a desk-mounted Franka FR3 arm moves cubes on its desk.

FrankaPickPlace3D-o1 (upstream kindergarden 0.2.5's task): a 5 cm cube lies on the desk in front
of the arm; the goal region is a 20 × 15 cm box on the desk top, up to 20 cm above it. The model
reads the goal's ``on`` atoms and their regions from the task file.

Concepts:

* ``HandEmpty(robot)``: the fingers are open (measured closure below 0.2).
* ``Holding(robot, cube)``: the fingers are closed and the pinch point is within 4 cm of the
  cube's centre, which is at least 1 cm above where it rests on the desk.
* ``Loose(cube)``: not held and not in its goal region.
* ``Placed(cube)``: not held and in its goal region (the env's own ``on`` test, so the goal
  atoms imply the env's goal).

Operators: ``Pick(?robot, ?cube)`` (pre HandEmpty, Loose; add Holding; delete HandEmpty, Loose)
and ``Place(?robot, ?cube)`` (pre Holding; add HandEmpty, Placed; delete Holding). Goal: every
goal cube Placed, and HandEmpty.

Skills: the FR3's 8-D action is 7 joint deltas (±0.1 rad) and a gripper command, tracked by the
env's position servos. A controller here (:class:`FrankaController`) follows joint targets
closed-loop: every step it sends the clipped error to the current :class:`Move`'s target and
moves on once every joint is within the move's tolerance (and its minimum number of steps has
passed, for the moves that close or open the hand); a move not reached within its step budget
raises :class:`~kinder_gym.skills.SkillFailure`. Targets come from the FR3 description's mink IK
(:func:`kinder_garden3d.robot.fr3.fr3_description` with
:class:`~kinder_garden3d.robot.ik.InverseKinematics`), seeded from the previous target so that
the arm stays on one branch; the gripper points straight down and closes across two of the
cube's faces (the pair whose heading is nearest to the arm's forward direction).

* Pick: move the pinch point 15 cm above the cube, descend to a sampled height about the cube's
  centre, close, and lift back to 15 cm above where the cube was.
* Place: keep the held cube's offset from the pinch point, move it above a sampled spot of its
  goal region at the current height, lower it until its bottom is 5 mm above the desk top,
  open, and rise 10 cm.

Parameter spaces: Pick ``(depth,)`` in [0, 1]: the fingers close 1 cm below (0) to 1 cm above
(1) the cube's centre. Place ``(u, v)`` in [0, 1]²: the cube's centre at fractions (u, v) of the
goal region box's x and y extents, shrunk by 3.5 cm on every side (the cube's half-size and
1 cm).

Differences from upstream: upstream 0.2.5 has no bilevel-planning model for this family, so this
one is new. The env's goal (the cube's centre in the region's box, up to 20 cm above the desk)
already holds while the held cube passes over the region, so an episode usually ends during the
Place; the planner counts a rollout that reaches the env's goal as done. Imports
kinder_garden3d (the ``[3d]`` extra).

Measured (2026-11-27, development seeds, ``kinder bench run -a bilevel_planning --env
kinder/FrankaPickPlace3D-o1-v0 --executor inline``): BP success 1.00 with ``--seeds 1000
--episodes 5`` (42 steps, 0.16 s of inference per episode) and 1.00 with ``--seeds 1000-1004
--episodes 10`` (50 of 50; 41 steps, 0.23 s).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache
from typing import Literal, TypeAlias

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.object_types import FR3_ROBOT_TYPE, MOVABLE_TYPE
from kinder_garden3d.robot.description import forward_kinematics, matrix_to_quat_xyzw
from kinder_garden3d.robot.fr3 import fr3_description
from kinder_garden3d.robot.ik import InverseKinematics
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models import hand
from kinder_gym.models.dynamic3d.tidybot import (
    Dynamic3DContext,
    dynamic3d_model,
    placement_goal,
    region_spot,
)
from kinder_gym.motion_planning import FloatArray, wrap_angle
from kinder_gym.skills import Controller, SkillFailure

ARM_FEATURES = tuple(f"pos_arm_joint{i}" for i in range(1, 8))
BASE_FEATURES = ("pos_base_x", "pos_base_y", "pos_base_rot")
#: Bound of every joint delta in the action (rad).
MAX_DELTA = 0.1
#: Gripper closure above which the hand counts as closed.
CLOSED = 0.2
#: Steps a move that closes or opens the hand lasts at least.
GRIP_STEPS = 8
#: Height (m) of the pinch point above the cube's centre before the descent and after the lift.
ABOVE = 0.15
#: Height (m) the pinch point rises after letting go.
RISE = 0.10
#: Height (m) of the held cube's bottom above the desk top when the hand opens.
RELEASE_GAP = 0.005
#: Margin (m) kept inside the goal region's box when sampling the spot of the cube's centre.
MARGIN = 0.035
#: Distance (m) from the pinch point within which a lifted cube counts as held.
HOLD_RADIUS = 0.04


@dataclass(frozen=True)
class FrankaContext(Dynamic3DContext):
    """What the FrankaPickPlace3D controllers need besides the state."""

    #: Goal region of each goal cube, by name.
    regions: dict[str, str]
    #: Height (m) of the arm's mount (the env puts it at its table's nominal top).
    mount_z: float


@dataclass(frozen=True)
class Move:
    """One joint-space target of a :class:`FrankaController`.

    Attributes:
        arm: Arm joint targets; None keeps the arm where it is at the move's start.
        gripper: Gripper command during the move (0 open, 1 closed).
        tol: Largest arm joint error (rad) at which the move counts as reached.
        min_steps: Steps the move lasts at least (to let the gripper close or open).
        max_steps: Steps after which an unreached move fails.
    """

    arm: tuple[float, ...] | None
    gripper: float
    tol: float = 0.01
    min_steps: int = 0
    max_steps: int = 100


#: A move, or a function of the state at which it starts giving more (possibly lazy) moves.
MoveSource: TypeAlias = "Move | Callable[[ObjectCentricState], Sequence[MoveSource]]"


@cache
def _ik() -> InverseKinematics:
    return InverseKinematics(desc=fr3_description())


def arm_joints(state: ObjectCentricState, robot: Object) -> FloatArray:
    """The 7 measured arm joint angles."""
    return np.array([state.get(robot, f) for f in ARM_FEATURES])


def _base(state: ObjectCentricState, robot: Object) -> tuple[float, float, float]:
    x, y, yaw = (float(state.get(robot, f)) for f in BASE_FEATURES)
    return x, y, yaw


def pinch_frame(ctx: FrankaContext, state: ObjectCentricState) -> FloatArray:
    """The world pose (4 × 4) of the point between the finger pads."""
    robot = ctx.robot
    tfs = forward_kinematics(
        _base(state, robot), arm_joints(state, robot), base_z=ctx.mount_z, desc=fr3_description()
    )
    return np.asarray(tfs["pinch_site"], dtype=np.float64)


def down_quat(yaw: float) -> FloatArray:
    """Orientation (x, y, z, w) of a gripper pointing straight down, its x axis heading ``yaw``
    (the fingers close along its y axis)."""
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])  # Rz(yaw) · Rx(π)
    return matrix_to_quat_xyzw(rot)


def solve_ik(
    ctx: FrankaContext,
    state: ObjectCentricState,
    position: FloatArray,
    yaw: float,
    near: FloatArray,
) -> FloatArray:
    """Arm joints putting the pinch point at ``position`` pointing down with heading ``yaw``,
    solved from ``near`` (so on its branch); SkillFailure when there is none."""
    result = _ik().solve(
        np.asarray(position, dtype=np.float64),
        down_quat(yaw),
        base_pose=_base(state, ctx.robot),
        base_z=ctx.mount_z,
        initial_arm_joints=np.asarray(near, dtype=np.float64),
        restarts=0,
        position_tolerance=1e-3,
        orientation_tolerance=1e-2,
        max_iterations=300,
    )
    if not result.success:
        raise SkillFailure(f"no FR3 IK solution for the pinch point at {np.round(position, 3)}")
    return np.asarray(result.arm_joints, dtype=np.float64)


def grasp_yaw(state: ObjectCentricState, cube: Object, forward: float) -> float:
    """The heading across two of the cube's faces nearest to ``forward`` (rad)."""
    q = [state.get(cube, f) for f in ("qw", "qx", "qy", "qz")]
    yaw = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
    k = round((forward - yaw) / (math.pi / 2))
    return wrap_angle(yaw + k * math.pi / 2)


class FrankaController(Controller):
    """Joint-target following for the FR3 (see the module docstring). The first object is the
    robot; subclasses implement :meth:`plan`. A pick sets :attr:`hand_must_be` to ``"open"``, a
    place to ``"closed"``: the skill is initiable only with the gripper so."""

    hand_must_be: Literal["open", "closed"]

    def initiable(self, state: ObjectCentricState) -> bool:
        closed = bool(state.get(self.objects[0], "pos_gripper") >= CLOSED)
        return closed == (self.hand_must_be == "closed")

    @abc.abstractmethod
    def plan(self, state: ObjectCentricState) -> list[MoveSource]:
        """The moves from ``state`` (raise SkillFailure when the skill cannot run)."""

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        self._queue: list[MoveSource] = list(self.plan(state))
        self._current: Move | None = None
        self._target: FloatArray = arm_joints(state, self.objects[0])
        self._steps = 0
        self._done = False
        self._advance(state)

    def _reached(self, state: ObjectCentricState) -> bool:
        assert self._current is not None
        err = np.abs(self._target - arm_joints(state, self.objects[0])).max()
        return self._steps >= self._current.min_steps and bool(err <= self._current.tol)

    def _advance(self, state: ObjectCentricState) -> None:
        """Pop moves until one is not yet reached (expanding lazy ones)."""
        while self._current is None or self._reached(state):
            self._current = None
            if not self._queue:
                self._done = True
                return
            nxt = self._queue.pop(0)
            if callable(nxt):
                self._queue[:0] = list(nxt(state))
                continue
            self._current = nxt
            here = arm_joints(state, self.objects[0])
            self._target = here if nxt.arm is None else np.asarray(nxt.arm, dtype=np.float64)
            self._steps = 0

    def step(self) -> FloatArray:
        assert self.state is not None
        move = self._current
        if move is None:
            return np.zeros(8)
        err = self._target - arm_joints(self.state, self.objects[0])
        if self._steps >= move.max_steps:
            raise SkillFailure(
                f"{type(self).__name__}: a move did not reach its target in {move.max_steps} "
                f"steps (arm error {np.abs(err).max():.3f})"
            )
        self._steps += 1
        return np.array([*np.clip(err, -MAX_DELTA, MAX_DELTA), move.gripper])

    def observe(self, state: ObjectCentricState) -> None:
        super().observe(state)
        self._advance(state)

    def terminated(self) -> bool:
        return self._done


def _grip(command: float) -> Move:
    return Move(None, command, tol=1.0, min_steps=GRIP_STEPS)


class PickController(FrankaController):
    """Pick a cube up from the desk top-down. Objects: ``(robot, cube)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = "(depth,): the fingers close 0.02·depth − 0.01 metres above the cube's centre."
    hand_must_be = "open"

    def plan(self, state: ObjectCentricState) -> list[MoveSource]:
        ctx: FrankaContext = self.context
        robot, cube = self.objects
        c = np.array([state.get(cube, f) for f in ("x", "y", "z")])
        yaw = grasp_yaw(state, cube, _base(state, robot)[2])
        above = c + np.array([0.0, 0.0, ABOVE])
        grasp = c + np.array([0.0, 0.0, 0.02 * float(self.params[0]) - 0.01])
        q_above = solve_ik(ctx, state, above, yaw, arm_joints(state, robot))
        q_grasp = solve_ik(ctx, state, grasp, yaw, q_above)
        q_lift = solve_ik(ctx, state, above, yaw, q_grasp)
        return [
            Move(tuple(q_above), 0.0),
            Move(tuple(q_grasp), 0.0),
            _grip(1.0),
            Move(tuple(q_lift), 1.0, tol=0.02),
        ]


class PlaceController(FrankaController):
    """Put the held cube down on a spot of its goal region. Objects: ``(robot, cube)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(u, v): the cube's centre at fractions (u, v) of the goal region box's x and y extents "
        "(shrunk by 0.035 m on every side)."
    )
    hand_must_be = "closed"

    def plan(self, state: ObjectCentricState) -> list[MoveSource]:
        ctx: FrankaContext = self.context
        robot, cube = self.objects
        region = ctx.regions[cube.name]
        u, v = (float(p) for p in self.params)
        spot = region_spot(ctx.env, state, region, 0, u, v, margin=MARGIN)
        surface = float(ctx.env.regions.transform(state, region)[2, 3])  # type: ignore[attr-defined]
        tf = pinch_frame(ctx, state)
        pinch = tf[:3, 3]
        yaw = math.atan2(float(tf[1, 0]), float(tf[0, 0]))
        centre = np.array([state.get(cube, f) for f in ("x", "y", "z")])
        offset = pinch - centre
        bottom = float(centre[2]) - 0.5 * state.get(cube, "bb_z")
        over = np.array([*(spot + offset[:2]), pinch[2]])
        release = over - np.array([0.0, 0.0, bottom - surface - RELEASE_GAP])
        q_over = solve_ik(ctx, state, over, yaw, arm_joints(state, robot))
        q_release = solve_ik(ctx, state, release, yaw, q_over)
        q_rise = solve_ik(ctx, state, release + np.array([0.0, 0.0, RISE]), yaw, q_release)
        return [
            Move(tuple(q_over), 1.0, tol=0.02),
            Move(tuple(q_release), 1.0, tol=0.02),
            _grip(0.0),
            Move(tuple(q_rise), 0.0),
        ]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The FrankaPickPlace3D planning model (cubes on the desk into desk regions)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    robot_obj = objects["robot"]
    regions = dict(placement_goal(env, "FrankaPickPlace3D", lambda atom: atom[0] == "on"))
    for name in regions:
        if name not in objects or objects[name].type != MOVABLE_TYPE:
            raise ValueError(
                f"FrankaPickPlace3D model: goal object {name!r} is not a movable object"
            )
    goal_objs = tuple(sorted(objects[n] for n in regions))
    mount = str(env.task.robot_mount)  # type: ignore[attr-defined]
    mount_z = float(env.scene.fixtures[mount].frames["top"][2, 3])  # type: ignore[attr-defined]
    ctx = FrankaContext(env, robot_obj, regions, mount_z)

    HandEmpty = Predicate("HandEmpty", (FR3_ROBOT_TYPE,))
    Holding = Predicate("Holding", (FR3_ROBOT_TYPE, MOVABLE_TYPE))
    Loose = Predicate("Loose", (MOVABLE_TYPE,))
    Placed = Predicate("Placed", (MOVABLE_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        closed = state.get(robot_obj, "pos_gripper") >= CLOSED
        atoms = set() if closed else {HandEmpty.ground([robot_obj])}
        pinch = pinch_frame(ctx, state)[:3, 3]
        on = env.goal_atoms(state)  # type: ignore[attr-defined]
        for o in goal_objs:
            pos = np.asarray(state[o][:3])
            region = regions[o.name]
            surface = float(env.regions.transform(state, region)[2, 3])  # type: ignore[attr-defined]
            rest_z = surface + 0.5 * state.get(o, "bb_z")
            if closed and pos[2] > rest_z + 0.01 and np.linalg.norm(pos - pinch) < HOLD_RADIUS:
                atoms.add(Holding.ground([robot_obj, o]))
            elif on[f"on({o.name}, {region})"]:
                atoms.add(Placed.ground([o]))
            else:
                atoms.add(Loose.ground([o]))
        return frozenset(atoms)

    c = Variable("?cube", MOVABLE_TYPE)
    pick = hand.pick_operator("Pick", HandEmpty, Holding, c, [Loose.lift([c])])
    place = hand.place_operator("Place", HandEmpty, Holding, c, [Placed.lift([c])])
    return dynamic3d_model(
        "franka_pick_place3d",
        ctx,
        [HandEmpty, Holding, Loose, Placed],
        [(pick, PickController), (place, PlaceController)],
        {HandEmpty.ground([robot_obj])} | {Placed.ground([g]) for g in goal_objs},
        abstraction,
        goal_objs,
        300,
        types=[FR3_ROBOT_TYPE, MOVABLE_TYPE],
    )


__all__: Sequence[str] = [
    "FrankaController",
    "Move",
    "PickController",
    "PlaceController",
    "create_model",
    "down_quat",
    "pinch_frame",
]
