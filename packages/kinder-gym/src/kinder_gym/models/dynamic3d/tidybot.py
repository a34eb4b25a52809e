"""Controllers and kinematics for the Dynamic3D (MuJoCo) mobile manipulator.

The robot is driven through the env's 11-D delta action: base ``(x, y, yaw)`` targets and 7 arm
joint targets are the *measured* configuration plus bounded deltas (±0.1), tracked by position
servos (base) and PD control with gravity compensation (arm); the last entry is the gripper
command in [0, 1] (1 = closed). Physics lag behind the targets, so a controller here follows
:class:`Segment` targets closed-loop: every step it sends the clipped error to the current
segment's target and moves on once the measured configuration is within the segment's tolerance
(and its minimum number of steps has passed, for gripper segments). A segment not reached within
its step budget raises :class:`~kinder_gym.skills.SkillFailure`, so planners resample.

Segments may be produced lazily (a callable of the state at which they start), because Cartesian
targets depend on where the base actually stopped. Kinematics: pure-numpy forward kinematics of
the robot description and mink IK (:func:`ik_near`, which prefers the solution nearest the current
joints). Imports kinder_garden3d (the ``[3d]`` extra).

This is the mobile manipulator's base module, which every Dynamic3D planning model imports (never
a sibling model): the robot's constants (gripper closure, grasp pitch, ready pose, chassis size),
base-path geometry (:func:`segment_point_distance`, :func:`segment_rect_distance`,
:func:`chassis_clear_of_box`, :func:`clear_of_points`, :func:`floor_points`), the drive
(:meth:`Dynamic3DController.drive`), the context every controller gets
(:class:`Dynamic3DContext`), the side grasp of an object on the floor (:func:`face_heading`,
:func:`grasp_and_lift`, :class:`FloorPickController`), the top-down moves with the base fixed
(:class:`TopDownController`), the task's goal placements (:func:`placement_goal`,
:func:`region_spot`), the hand's predicates (:func:`hand_predicates`) and the model itself
(:func:`dynamic3d_model`).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal, TypeAlias

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, Type
from kinder_garden3d.dynamic3d.env import HOME_ARM
from kinder_garden3d.dynamic3d.geometry import quat_yaw
from kinder_garden3d.dynamic3d.object_types import FIXTURE_TYPE, MOVABLE_TYPE, ROBOT_TYPE
from kinder_garden3d.robot.description import (
    forward_kinematics,
    matrix_to_quat_xyzw,
    robot_description,
)
from kinder_garden3d.robot.ik import InverseKinematics
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models import hand
from kinder_gym.motion_planning import FloatArray, wrap_angle
from kinder_gym.operators import LiftedOperator
from kinder_gym.skills import Controller, Skill, SkillFailure

#: The retracted arm (the env's start pose, upstream's retract pose), carried while the base drives.
HOME = np.array(HOME_ARM, dtype=np.float64)
BASE_FEATURES = ("pos_base_x", "pos_base_y", "pos_base_rot")
ARM_FEATURES = tuple(f"pos_arm_joint{i}" for i in range(1, 8))
#: Bound of every delta in the action (m, rad).
MAX_DELTA = 0.1
#: Speed (rad per action) at which the arm's joints follow a far target: about half the delta,
#: measured on the Shelf3D and ConstrainedCupboard3D picks.
ARM_SPEED = 0.05
_LOW, _HIGH = robot_description().arm_joint_limits
#: The continuous arm joints (no limits): their errors are wrapped the short way round.
CONTINUOUS = ~np.isfinite(_LOW)
#: Gripper closure above which the hand counts as closed.
CLOSED = 0.2
#: Steps a segment that closes or opens the hand lasts at least.
GRIP_STEPS = 8
#: Gripper command that releases a held cube: the pads 4.7 cm apart.
RELEASE = 0.45
#: Radius (m) of a circle around the 0.4 m square chassis, plus a margin.
CHASSIS_RADIUS = 0.3
#: Distance (m) the base centre keeps from cubes on the floor while it drives. The chassis'
#: underside is 2 cm above the floor, the height of a cube, so it passes over them; measured on
#: Shelf3D-o2/o4, keeping the whole chassis clear only made most standoffs unreachable.
CUBE_CLEARANCE = 0.05
#: Height (m) of the pinch point when the fingers close on a cube lying on the floor.
GRASP_Z = 0.02
#: Pitch of the gripper below the horizontal while grasping and carrying from the side (rad).
PITCH = math.radians(45.0)
#: Pitch of a top-down gripper (rad).
DOWN = math.pi / 2
#: Arm joints from which IK finds the forward-reaching, elbow-up grasp configurations.
READY = np.array([0.0, 0.26, math.pi, -2.27, 0.0, 0.96, math.pi / 2])
#: Height (m) of the pinch point while :class:`TopDownController` moves between objects on the
#: kitchen island; a held object's bottom then clears the tallest object of Rearrange3D (the
#: can, 12 cm) by more than 4 cm.
TRAVEL_Z = 0.75
#: Largest arm joint error (rad) at which a move ending with a held object (or at the travel
#: height) counts as reached: the can's weight leaves about 8 mrad of steady-state error.
LOADED_TOL = 0.012
#: Sideways shifts (m) of the base tried, smallest first, when a top-down pose is out of reach.
BASE_SHIFTS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5)


def base_pose(state: ObjectCentricState, robot: Object) -> FloatArray:
    """The measured base pose ``(x, y, yaw)``."""
    return np.array([state.get(robot, f) for f in BASE_FEATURES])


def arm_joints(state: ObjectCentricState, robot: Object) -> FloatArray:
    """The 7 measured arm joint angles."""
    return np.array([state.get(robot, f) for f in ARM_FEATURES])


def pinch_position(base: FloatArray, arm: FloatArray) -> FloatArray:
    """World position of the point between the finger pads for a configuration."""
    tf = forward_kinematics((float(base[0]), float(base[1]), float(base[2])), arm)["pinch_site"]
    return np.asarray(tf[:3, 3], dtype=np.float64)


def top_down_yaw(base: FloatArray, arm: FloatArray) -> float:
    """Heading of a top-down gripper (the one :func:`gripper_quat` takes)."""
    tf = forward_kinematics((float(base[0]), float(base[1]), float(base[2])), arm)["pinch_site"]
    across = tf[:3, 1]  # the fingers close along the gripper's y axis
    return math.atan2(float(across[1]), float(across[0])) - math.pi / 2


def grasp_yaws(state: ObjectCentricState, obj: Object, heading: float) -> list[float]:
    """Gripper headings closing across the object's faces, nearest to ``heading`` first."""
    yaw = quat_yaw(np.asarray(state[obj][3:7]))
    cands = [wrap_angle(yaw + k * math.pi / 2) for k in range(4)]
    return sorted(cands, key=lambda c: abs(wrap_angle(c - heading)))


def face_heading(state: ObjectCentricState, obj: Object, wanted: float) -> float:
    """The heading facing one of the object's four side faces (the object's yaw plus a multiple
    of π/2) nearest to ``wanted``: the gripper then closes across that face."""
    yaw = quat_yaw(np.asarray(state[obj][3:7]))
    k = round((wanted - yaw) / (math.pi / 2))
    return wrap_angle(yaw + k * math.pi / 2)


def floor_points(
    state: ObjectCentricState, objects: Sequence[Object], skip: Object | None, below: float
) -> list[FloatArray]:
    """The positions (x, y) of the ``objects`` other than ``skip`` whose centres are lower than
    ``below`` (m): those on the floor, which a driving base has to keep clear of."""
    return [
        np.array([state.get(o, "x"), state.get(o, "y")])
        for o in objects
        if o != skip and state.get(o, "z") < below
    ]


def face_approach(
    state: ObjectCentricState, obj: Object, wanted: float
) -> tuple[FloatArray, float, FloatArray]:
    """The approach of a side grasp at the object's centre (x, y): the heading of
    :func:`face_heading` and its unit vector."""
    heading = face_heading(state, obj, wanted)
    direction = np.array([math.cos(heading), math.sin(heading)])
    return np.array([state.get(obj, "x"), state.get(obj, "y")]), heading, direction


def segment_point_distance(a: FloatArray, b: FloatArray, p: FloatArray) -> float:
    """Distance between the segment from ``a`` to ``b`` and the point ``p``."""
    ab = b - a
    t = 0.0 if not ab.any() else float(np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0))
    return float(np.linalg.norm(a + t * ab - p))


def segment_rect_distance(
    a: FloatArray, b: FloatArray, centre: FloatArray, axes: FloatArray, half: FloatArray
) -> float:
    """Distance between a segment and a rotated rectangle (sampled along the segment every
    2 cm); ``axes``' columns are the rectangle's unit axes, ``half`` its half-extents."""
    n = max(2, math.ceil(float(np.linalg.norm(b - a)) / 0.02) + 1)
    pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    local = (pts - centre) @ axes
    excess = np.maximum(np.abs(local) - half, 0.0)
    return float(np.min(np.linalg.norm(excess, axis=1)))


def placement_goal(
    env: ObjectCentricEnv, model: str, accept: Callable[[tuple[Any, ...]], bool]
) -> list[tuple[str, str]]:
    """``(object, region)`` of every atom of the task's goal, an ``and`` of placement atoms
    ``(predicate, object, region)`` (or one); a ValueError names ``model`` and the first atom
    that ``accept`` refuses."""
    goal = env.task.goal  # type: ignore[attr-defined]
    placed = []
    for atom in goal[1] if goal[0] == "and" else [goal]:
        if not accept(atom):
            raise ValueError(f"{model} model: unsupported goal atom {atom!r}")
        placed.append((str(atom[1]), str(atom[2])))
    return placed


def yaw_axes(yaw: float) -> FloatArray:
    """The unit axes (x, y), as columns, of a frame turned by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def chassis_clear_of_box(
    a: FloatArray,
    b: FloatArray,
    centre: FloatArray,
    axes: FloatArray,
    half: FloatArray,
    margin: float,
) -> bool:
    """Whether the chassis (:data:`CHASSIS_RADIUS` around the base centre) driving straight from
    ``a`` to ``b`` stays more than ``margin`` (m) clear of a rectangle (see
    :func:`segment_rect_distance`)."""
    return segment_rect_distance(a, b, centre, axes, half) > CHASSIS_RADIUS + margin


def clear_of_points(
    a: FloatArray, b: FloatArray, points: Sequence[FloatArray], clearance: float
) -> bool:
    """Whether the base centre driving straight from ``a`` to ``b`` keeps more than
    ``clearance`` (m) from every point (x, y) (objects on the floor, :func:`floor_points`)."""
    return all(segment_point_distance(a, b, p) > clearance for p in points)


def region_spot(
    env: ObjectCentricEnv,
    state: ObjectCentricState,
    region: str,
    box: int,
    u: float,
    v: float,
    margin: float = 0.0,
) -> FloatArray:
    """The world (x, y) at fractions ``(u, v)`` of the x and y extents of box ``box`` of a goal
    region, shrunk by ``margin`` (m) on every side, in the region's frame (which moves with what
    the region is attached to)."""
    b = env.task.regions[region].boxes[box]  # type: ignore[attr-defined]
    frame = env.regions.transform(state, region)  # type: ignore[attr-defined]
    lo = np.asarray(b[:2], dtype=np.float64) + margin
    hi = np.asarray(b[3:5], dtype=np.float64) - margin
    local = np.array([*(lo + np.array([u, v]) * (hi - lo)), 0.0])
    return np.asarray((frame[:3, :3] @ local + frame[:3, 3])[:2], dtype=np.float64)


def hand_predicates(held: Type = MOVABLE_TYPE) -> tuple[Predicate, Predicate]:
    """``HandEmpty(robot)`` and ``Holding(robot, held)``, the hand's predicates of every
    Dynamic3D model (each model's abstraction decides when they hold)."""
    return Predicate("HandEmpty", (ROBOT_TYPE,)), Predicate("Holding", (ROBOT_TYPE, held))


def hand_state(
    state: ObjectCentricState, robot: Object, hand_empty: Predicate
) -> tuple[set[GroundAtom], bool, FloatArray]:
    """What every Dynamic3D abstraction starts from: ``{HandEmpty(robot)}`` when the gripper is
    open (else no atom), whether it is closed, and the pinch point (to tell which object it
    holds)."""
    closed = state.get(robot, "pos_gripper") >= CLOSED
    atoms = set() if closed else {hand_empty.ground([robot])}
    return atoms, closed, pinch_position(base_pose(state, robot), arm_joints(state, robot))


def pick_operator(item: Variable, source: Predicate) -> LiftedOperator:
    """``Pick(?robot, item)``: with the hand empty and ``source(item)``, hold ``item``
    (``HandEmpty`` and ``source(item)`` deleted)."""
    return hand.pick_operator("Pick", *hand_predicates(), item, [source.lift([item])])


def place_operator(item: Variable, target: Predicate, name: str = "Place") -> LiftedOperator:
    """``name(?robot, item)``: holding ``item``, let go of it so that ``target(item)`` holds
    (``HandEmpty`` and ``target(item)`` added, ``Holding`` deleted)."""
    return hand.place_operator(name, *hand_predicates(), item, [target.lift([item])])


def pick_place_domain(
    item: str,
) -> tuple[tuple[Predicate, Predicate, Predicate, Predicate], LiftedOperator, LiftedOperator]:
    """The predicates ``(HandEmpty, Holding, OnGround, OnShelf)`` and the ``Pick(?robot, item)``
    and ``Place(?robot, item, ?cupboard)`` operators of a floor-to-cupboard model (Shelf3D,
    ConstrainedCupboard3D); ``item`` names the object variable (``"?cube"``)."""
    hand_empty, holding = hand_predicates()
    on_ground = Predicate("OnGround", (MOVABLE_TYPE,))
    on_shelf = Predicate("OnShelf", (MOVABLE_TYPE, FIXTURE_TYPE))
    c = Variable(item, MOVABLE_TYPE)
    f = Variable("?cupboard", FIXTURE_TYPE)
    pick = pick_operator(c, on_ground)
    place = hand.place_operator(
        "Place", hand_empty, holding, c, [on_shelf.lift([c, f])], params=[f]
    )
    return (hand_empty, holding, on_ground, on_shelf), pick, place


def dynamic3d_model(
    name: str,
    ctx: Dynamic3DContext,
    predicates: Sequence[Predicate],
    skills: Sequence[Skill | tuple[LiftedOperator, type[Controller]]],
    goal: Iterable[GroundAtom],
    abstraction: Callable[[ObjectCentricState], frozenset[GroundAtom]],
    objects: Sequence[Object],
    horizon: int,
    types: Sequence[Type] = (ROBOT_TYPE, MOVABLE_TYPE),
    step_limit: bool = False,
    monotone: Sequence[Predicate] = (),
    **options: Any,
) -> PlanningModel:
    """A Dynamic3D planning model over the object ``types`` (the robot's and the movables'), the
    ``skills`` (an ``(operator, controller class)`` pair is a skill whose controllers are given
    ``ctx``) and the ``goal`` atoms, whatever the episode's state; operators are grounded over
    the robot and ``objects``, a skill takes at most ``horizon`` steps. With ``step_limit`` the
    planner plans within the env's episode step limit; ``monotone`` are the model's monotone
    predicates (see :class:`~kinder_gym.model.PlanningModel`), and ``options`` (such as
    ``operator_filter``) go to it."""
    goal_atoms = frozenset(goal)
    robot = ctx.robot
    listed = list(objects)
    spec = ctx.env.spec
    return PlanningModel(
        name=name,
        env=ctx.env,
        types=tuple(types),
        predicates=tuple(predicates),
        skills=tuple(s if isinstance(s, Skill) else Skill(*s, ctx) for s in skills),
        goal_fn=lambda state: goal_atoms,
        abstraction_fn=abstraction,
        objects_fn=lambda state: [robot, *listed],
        max_skill_horizon=horizon,
        max_episode_steps=spec.max_episode_steps if step_limit and spec is not None else None,
        monotone_predicates=frozenset(p.name for p in monotone),
        **options,
    )


def gripper_quat(yaw: float, pitch: float) -> FloatArray:
    """Gripper orientation (x, y, z, w) pointing along heading ``yaw``, tilted ``pitch`` down
    (π/2: straight down); the fingers close horizontally, across the heading."""
    cy, sy = math.cos(yaw), math.sin(yaw)
    approach = np.array([math.cos(pitch) * cy, math.cos(pitch) * sy, -math.sin(pitch)])
    across = np.array([-sy, cy, 0.0])
    return matrix_to_quat_xyzw(np.stack([np.cross(across, approach), across, approach], axis=1))


_IK: InverseKinematics | None = None


def ik_near(
    position: FloatArray,
    quat: FloatArray,
    base: FloatArray,
    near: FloatArray,
    position_tolerance: float = 1e-3,
    orientation_tolerance: float = 1e-2,
) -> FloatArray:
    """Arm joints putting the pinch point at ``position`` with orientation ``quat`` (base fixed),
    solved from ``near`` so the solution stays on its branch; SkillFailure when there is none."""
    global _IK
    if _IK is None:
        _IK = InverseKinematics(free_base=False)
    result = _IK.solve(
        np.asarray(position, dtype=np.float64),
        np.asarray(quat, dtype=np.float64),
        base_pose=(float(base[0]), float(base[1]), float(base[2])),
        initial_arm_joints=np.asarray(near, dtype=np.float64),
        restarts=0,
        position_tolerance=position_tolerance,
        orientation_tolerance=orientation_tolerance,
        max_iterations=150,
    )
    if not result.success:
        raise SkillFailure(f"no IK solution for the pinch point at {np.round(position, 3)}")
    return np.asarray(result.arm_joints, dtype=np.float64)


def arm_turn(a: FloatArray, b: FloatArray) -> float:
    """The largest joint rotation (rad) from arm joints ``a`` to ``b`` (the continuous joints
    the short way round)."""
    d = np.asarray(b, dtype=np.float64) - np.asarray(a, dtype=np.float64)
    d[CONTINUOUS] = (d[CONTINUOUS] + math.pi) % (2 * math.pi) - math.pi
    return float(np.abs(d).max())


def nearest_ik(
    position: FloatArray, quat: FloatArray, base: FloatArray, arm: FloatArray, other: FloatArray
) -> FloatArray:
    """Of the IK solutions found from the arm joints ``arm`` and from ``other`` (a seed on a
    known-good branch), the one nearer ``arm``: it sets how long the arm takes to get there (from
    where a Place left the arm, the other seed's solution is often a wrist flip, 3 rad, away)."""
    found = []
    for seed in (arm, other):
        try:
            found.append(ik_near(position, quat, base, seed))
        except SkillFailure:
            continue
    if not found:
        raise SkillFailure(f"no IK solution for the pinch point at {np.round(position, 3)}")
    return min(found, key=lambda q: arm_turn(arm, q))


@dataclass(frozen=True)
class Segment:
    """One target of a :class:`Dynamic3DController`.

    Attributes:
        base: Base target ``(x, y, yaw)``; None keeps the base where it is at the segment start.
        arm: Arm joint targets; None keeps the arm where it is at the segment start.
        gripper: Gripper command during the segment (0 open, 1 closed).
        arm_tol: Largest arm joint error (rad) at which the segment counts as reached.
        base_tol: Largest base error (m, rad) at which the segment counts as reached.
        min_steps: Steps the segment lasts at least (e.g. to let the gripper close).
        max_steps: Steps after which an unreached segment fails.
        base_speed: Largest base step (m, rad per action); lower while carrying, so that the
            held object is not flung out of the fingers.
    """

    base: tuple[float, float, float] | None = None
    arm: tuple[float, ...] | None = None
    gripper: float = 0.0
    arm_tol: float = 0.02
    base_tol: float = 0.01
    min_steps: int = 0
    max_steps: int = 60
    base_speed: tuple[float, float] = (MAX_DELTA, MAX_DELTA)


#: A segment, or a function of the state at which it starts giving more (possibly lazy) segments.
SegmentSource: TypeAlias = "Segment | Callable[[ObjectCentricState], Sequence[SegmentSource]]"


def grip_segment(command: float, min_steps: int = GRIP_STEPS) -> Segment:
    """A segment that sets the gripper to ``command`` (1 closes, 0 opens) for at least
    ``min_steps`` steps with the base and the arm held where they are."""
    return Segment(gripper=command, arm_tol=1.0, base_tol=1.0, min_steps=min_steps)


@dataclass(frozen=True)
class Dynamic3DContext:
    """What every Dynamic3D controller needs besides the state: the env (its regions, task file
    and goal atoms) and the robot. A family's context adds its own objects."""

    env: ObjectCentricEnv
    robot: Object


def line_segments(
    state: ObjectCentricState,
    robot: Object,
    target: FloatArray,
    yaw: float,
    pitch: float,
    gripper: float,
    spacing: float = 0.03,
    arm_tol: float = 0.02,
    final_tol: float = 0.005,
    pitch_offsets: Sequence[float] = (0.0, -5.0, 5.0, -10.0, 10.0, -15.0, 15.0),
) -> list[Segment]:
    """Segments moving the pinch point along a straight line to ``target`` (base fixed), one IK
    solution every ``spacing`` metres, each seeded from the previous one.

    The gripper keeps heading ``yaw``; where a pose is out of reach its pitch drifts by the first
    of ``pitch_offsets`` (degrees, smallest first) that is reachable from one waypoint to the
    next."""
    base = base_pose(state, robot)
    q = arm_joints(state, robot)
    start = pinch_position(base, q)
    goal = np.asarray(target, dtype=np.float64)
    n = max(1, math.ceil(float(np.linalg.norm(goal - start)) / spacing))
    segments: list[Segment] = []
    for k in range(1, n + 1):
        point = start + (goal - start) * k / n
        best: tuple[float, FloatArray, float] | None = None
        for offset in pitch_offsets:
            cand = pitch + math.radians(offset)
            try:
                sol = ik_near(point, gripper_quat(yaw, cand), base, q)
            except SkillFailure:
                continue
            best = (float(np.abs(sol - q).max()), sol, cand)
            break  # the smallest pitch change that is reachable
        if best is None:
            raise SkillFailure(f"no IK solution for the pinch point at {np.round(point, 3)}")
        _, q, pitch = best
        tol = final_tol if k == n else arm_tol
        segments.append(Segment(arm=tuple(q), gripper=gripper, arm_tol=tol))
    return segments


def grasp_and_lift(
    robot: Object,
    heading: float,
    grasp: FloatArray | Callable[[ObjectCentricState], FloatArray],
    lift_z: float,
    spacing: float,
) -> list[SegmentSource]:
    """The end of a side grasp, with the gripper heading ``heading`` and pitched :data:`PITCH`
    down: descend along a straight line to the pinch point ``grasp`` (a point, or a function of
    the state the descent starts in, to follow an object the chassis may have nudged), close the
    hand, and lift the pinch point straight up to the height ``lift_z`` (an IK waypoint every
    ``spacing`` metres)."""

    def descend(s: ObjectCentricState) -> list[Segment]:
        point = grasp(s) if callable(grasp) else grasp
        return line_segments(s, robot, point, heading, PITCH, 0.0)

    def lift(s: ObjectCentricState) -> list[Segment]:
        here = pinch_position(base_pose(s, robot), arm_joints(s, robot))
        target = np.array([here[0], here[1], lift_z])
        return line_segments(s, robot, target, heading, PITCH, 1.0, spacing=spacing)

    return [descend, grip_segment(1.0), lift]


def drive_segment(
    state: ObjectCentricState,
    robot: Object,
    goal: FloatArray,
    arm: FloatArray,
    gripper: float,
    tol: float,
    speed: tuple[float, float] = (MAX_DELTA, MAX_DELTA),
    reach: bool = False,
) -> Segment:
    """A segment driving the base to ``goal`` ``(x, y, yaw)`` with the arm held at ``arm``, at
    most ``speed`` (m, rad) per action, with a step budget of the larger of the distance and the
    turn at that speed, plus 40. With ``reach`` the arm moves to ``arm`` while the base drives,
    and the budget also covers the arm's largest joint turn at :data:`ARM_SPEED`, plus 40."""
    start = base_pose(state, robot)
    dist = float(np.linalg.norm(goal[:2] - start[:2]))
    turn = abs(wrap_angle(float(goal[2] - start[2])))
    steps = math.ceil(max(dist / speed[0], turn / speed[1])) + 40
    if reach:
        steps = max(steps, math.ceil(arm_turn(arm_joints(state, robot), arm) / ARM_SPEED) + 40)
    return Segment(
        base=(float(goal[0]), float(goal[1]), float(goal[2])),
        arm=tuple(float(v) for v in arm),
        gripper=gripper,
        arm_tol=0.05,
        base_tol=tol,
        max_steps=steps,
        base_speed=speed,
    )


class Dynamic3DController(Controller):
    """Segment following for the Dynamic3D robot (see the module docstring).

    The context is the env. Subclasses implement :meth:`plan`; the first object is the robot.
    A pick sets :attr:`hand_must_be` to ``"open"``, a place to ``"closed"``: the skill is
    initiable only with the gripper so.
    """

    #: How the gripper must be for the skill to start (``None``: either way).
    hand_must_be: Literal["open", "closed"] | None = None

    def initiable(self, state: ObjectCentricState) -> bool:
        closed = bool(state.get(self.robot, "pos_gripper") >= CLOSED)
        if self.hand_must_be is None:
            return True
        return closed == (self.hand_must_be == "closed")

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        self._queue: list[SegmentSource] = list(self.plan(state))
        self._current: Segment | None = None
        self._anchor: tuple[FloatArray, FloatArray] | None = None
        self._steps = 0
        self._done = False
        self._advance(state)

    @property
    def robot(self) -> Object:
        """The robot object."""
        return self.objects[0]

    @abc.abstractmethod
    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        """The segments from ``state`` (raise SkillFailure when the skill cannot run)."""

    def drive(
        self,
        goal: FloatArray,
        arm: FloatArray,
        gripper: float,
        tol: float,
        speed: tuple[float, float] = (MAX_DELTA, MAX_DELTA),
    ) -> Segment:
        """:func:`drive_segment` from the state the controller last saw (in :meth:`plan`, the
        state the skill starts in)."""
        state = self.state
        assert state is not None
        return drive_segment(state, self.robot, goal, arm, gripper, tol, speed)

    def retract_arm(self, state: ObjectCentricState) -> list[SegmentSource]:
        """The move of the arm to :data:`HOME`, the pose it drives in; nothing when every joint
        is within 0.05 rad of it."""
        if np.abs(arm_joints(state, self.robot) - HOME).max() > 0.05:
            return [Segment(arm=tuple(float(v) for v in HOME), arm_tol=0.05, max_steps=80)]
        return []

    def _advance(self, state: ObjectCentricState) -> None:
        """Pop segments until one is not yet reached (expanding lazy ones)."""
        while True:
            if self._current is not None and not self._reached(self._current, state):
                return
            self._current = None
            if not self._queue:
                self._done = True
                return
            nxt = self._queue.pop(0)
            if callable(nxt):
                self._queue[:0] = list(nxt(state))
                continue
            self._current = nxt
            self._anchor = (base_pose(state, self.robot), arm_joints(state, self.robot))
            self._steps = 0

    def _targets(self, seg: Segment) -> tuple[FloatArray, FloatArray]:
        assert self._anchor is not None
        base = self._anchor[0] if seg.base is None else np.asarray(seg.base)
        arm = self._anchor[1] if seg.arm is None else np.asarray(seg.arm)
        return base, arm

    def _errors(self, seg: Segment, state: ObjectCentricState) -> tuple[FloatArray, FloatArray]:
        base_t, arm_t = self._targets(seg)
        db = base_t - base_pose(state, self.robot)
        db[2] = wrap_angle(float(db[2]))
        da = arm_t - arm_joints(state, self.robot)
        da[CONTINUOUS] = (da[CONTINUOUS] + math.pi) % (2 * math.pi) - math.pi
        return db, da

    def _reached(self, seg: Segment, state: ObjectCentricState) -> bool:
        if self._steps < seg.min_steps:
            return False
        db, da = self._errors(seg, state)
        return bool(np.abs(db).max() <= seg.base_tol and np.abs(da).max() <= seg.arm_tol)

    def step(self) -> FloatArray:
        assert self.state is not None
        seg = self._current
        if seg is None:
            return np.zeros(11)
        db, da = self._errors(seg, self.state)
        if self._steps >= seg.max_steps:
            raise SkillFailure(
                f"{type(self).__name__}: a motion did not reach its target in {seg.max_steps} "
                f"steps (base error {np.abs(db).max():.3f}, arm error {np.abs(da).max():.3f})"
            )
        self._steps += 1
        action = np.empty(11)
        lin, ang = seg.base_speed
        norm = float(np.hypot(db[0], db[1]))
        action[:2] = db[:2] * min(1.0, lin / norm) if norm > 0 else 0.0
        action[2] = np.clip(db[2], -ang, ang)
        action[3:10] = np.clip(da, -MAX_DELTA, MAX_DELTA)
        action[10] = seg.gripper
        return action

    def observe(self, state: ObjectCentricState) -> None:
        super().observe(state)
        self._advance(state)

    def terminated(self) -> bool:
        return self._done


class FloorPickController(Dynamic3DController):
    """Pick an object off the floor from the side. Objects: ``(robot, obj)``.

    Drive (through :meth:`route`) to stand :meth:`standoff` metres short of the grasp point
    (:meth:`approach`; :func:`face_approach` for the object's centre), and :func:`grasp_and_lift`
    the object at :meth:`grasp_z` to :attr:`lift_z`. The arm either stays retracted while the
    base drives and then reaches above the grasp point where the object is then (the chassis may
    nudge it on the way), or (:attr:`swing`) swings to above the grasp point while the base
    drives, passing 15 cm above the floor, and grasps where the object was when the skill
    started. A family says what the parameters mean."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    hand_must_be = "open"
    #: Distance (m) short of the object's centre, along the heading, where the fingers close.
    grasp_back = 0.005
    #: Height (m) to which the pinch point lifts the object, and the lift's IK waypoint spacing.
    lift_z = 0.15
    lift_spacing = 0.06
    #: Whether the arm swings to above the object while the base drives.
    swing = False
    #: Base tolerance (m, rad) at the waypoints of the route before its end.
    via_tol = 0.03

    @abc.abstractmethod
    def approach(
        self, state: ObjectCentricState, obj: Object
    ) -> tuple[FloatArray, float, FloatArray]:
        """The grasp point (x, y), the heading the base faces it along and that heading's unit
        vector (x, y)."""

    def standoff(self) -> float:
        """Distance (m) from the grasp point at which the base stops: 0.50–0.60 m."""
        return 0.50 + 0.10 * float(self.params[0])

    def route(self, state: ObjectCentricState, goal: FloatArray) -> list[FloatArray]:
        """The base poses to drive through, ending at ``goal`` (raise SkillFailure when no
        route is clear): straight there."""
        del state
        return [goal]

    def grasp_z(self, state: ObjectCentricState, obj: Object) -> float:
        """Height (m) of the pinch point when the fingers close."""
        del state, obj
        return GRASP_Z

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        robot, obj = self.objects[:2]
        dist = self.standoff()
        c, heading, direction = self.approach(state, obj)
        goal = np.array([*(c - dist * direction), heading])
        route = self.route(state, goal)
        quat = gripper_quat(heading, PITCH)
        grasp_z = self.grasp_z(state, obj)
        if self.swing:
            above = np.array([*(c - 0.01 * direction), 0.15])
            ready = nearest_ik(above, quat, goal, arm_joints(state, robot), READY)
            grasp = np.array([*(c - self.grasp_back * direction), grasp_z])
            return [
                *(drive_segment(state, robot, p, ready, 0.0, self.via_tol, reach=True)
                  for p in route[:-1]),
                drive_segment(state, robot, goal, ready, 0.0, 0.01, reach=True),
                *grasp_and_lift(robot, heading, grasp, self.lift_z, self.lift_spacing),
            ]  # fmt: skip

        def _at(s: ObjectCentricState, back: float, z: float) -> FloatArray:
            here = np.array([s.get(obj, "x"), s.get(obj, "y")])
            return np.array([*(here - back * direction), z])

        def grasp_at(s: ObjectCentricState) -> FloatArray:
            return _at(s, self.grasp_back, grasp_z)

        def reach_above(s: ObjectCentricState) -> list[Segment]:
            q = ik_near(_at(s, 0.01, 0.15), quat, base_pose(s, robot), READY)
            return [Segment(arm=tuple(float(v) for v in q), arm_tol=0.01, max_steps=80)]

        return [
            *self.retract_arm(state),
            *(self.drive(p, HOME, 0.0, self.via_tol) for p in route[:-1]),
            self.drive(goal, HOME, 0.0, 0.01),
            reach_above,
            *grasp_and_lift(robot, heading, grasp_at, self.lift_z, self.lift_spacing),
        ]


class TopDownController(Dynamic3DController):
    """Top-down moves of the pinch point with the base fixed (Rearrange3D, SortClutteredBlocks3D).

    ``travel_z`` is the height (m) of the pinch point between objects; ``grip`` the gripper
    command while moving there (set by :meth:`plan` of a subclass)."""

    travel_z = TRAVEL_Z
    grip = 0.0

    def to_travel(self, state: ObjectCentricState, xy: FloatArray, yaw: float) -> Segment:
        """One joint-space move to the pinch point above ``xy`` at the travel height."""
        robot = self.robot
        q = arm_joints(state, robot)
        near = READY if np.abs(q - HOME).max() < 0.05 else q
        target = np.array([float(xy[0]), float(xy[1]), self.travel_z])
        sol = ik_near(target, gripper_quat(yaw, DOWN), base_pose(state, robot), near)
        return Segment(arm=tuple(sol), gripper=self.grip, arm_tol=0.01, max_steps=80)

    def base_for(
        self, state: ObjectCentricState, points: Sequence[FloatArray], yaws: Sequence[float]
    ) -> tuple[FloatArray, float]:
        """A base pose from which the pinch point reaches every point top-down with one of
        ``yaws`` (tried in order), and that yaw: the current pose, else the current pose
        shifted sideways (along the base's own y axis, heading kept) towards the points by
        the first of :data:`BASE_SHIFTS` that works. SkillFailure when none does."""
        base = base_pose(state, self.robot)
        lateral = np.array([-math.sin(base[2]), math.cos(base[2])])
        side = 1.0 if float((np.mean(points, axis=0)[:2] - base[:2]) @ lateral) >= 0 else -1.0
        for shift in BASE_SHIFTS:
            b = base.copy()
            b[:2] += side * shift * lateral
            for yaw in yaws:
                try:
                    for p in points:
                        ik_near(p, gripper_quat(yaw, DOWN), b, READY)
                except SkillFailure:
                    continue
                return b, yaw
        raise SkillFailure(f"{type(self).__name__}: out of top-down reach from beside the base")

    def grasp_from_above(
        self, xy: FloatArray, grasp_z: float, yaw: float, opening: float, spacing: float = 0.03
    ) -> list[SegmentSource]:
        """Move the pinch point above ``xy`` at the travel height, descend to ``grasp_z`` (the
        hand at the command ``opening``, an IK waypoint every ``spacing`` metres), close the hand
        and lift back to the travel height; the gripper heads ``yaw``."""
        robot = self.robot

        def above(s: ObjectCentricState) -> list[Segment]:
            return [self.to_travel(s, xy, yaw)]

        def descend(s: ObjectCentricState) -> list[Segment]:
            target = np.array([*xy, grasp_z])
            return line_segments(s, robot, target, yaw, DOWN, opening, spacing=spacing)

        def lift(s: ObjectCentricState) -> list[Segment]:
            p = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            target = np.array([p[0], p[1], self.travel_z])
            return line_segments(
                s, robot, target, yaw, DOWN, 1.0, spacing=0.05, final_tol=LOADED_TOL
            )

        return [above, descend, grip_segment(1.0), lift]

    def held(
        self, state: ObjectCentricState, obj: Object
    ) -> tuple[FloatArray, float, FloatArray, float]:
        """The pinch point, the heading of the top-down gripper, the held object's centre
        relative to the pinch point and the height of the object's bottom."""
        base = base_pose(state, self.robot)
        arm = arm_joints(state, self.robot)
        pinch = pinch_position(base, arm)
        c = np.array([state.get(obj, f) for f in ("x", "y", "z")])
        bottom = float(c[2]) - 0.5 * state.get(obj, "bb_z")
        return pinch, top_down_yaw(base, arm), c - pinch, bottom

    def release_at(
        self, xy: FloatArray, release_z: float, yaw: float, opening: float
    ) -> list[SegmentSource]:
        """Carry the held object with the pinch point at the travel height to above ``xy``,
        lower it to ``release_z``, open the hand to the command ``opening`` and rise back to the
        travel height; the gripper heads ``yaw``."""
        robot = self.robot

        def carry(s: ObjectCentricState) -> list[Segment]:
            goal = np.array([*xy, self.travel_z])
            return line_segments(s, robot, goal, yaw, DOWN, 1.0, spacing=0.05, final_tol=LOADED_TOL)

        def lower(s: ObjectCentricState) -> list[Segment]:
            goal = np.array([*xy, release_z])
            return line_segments(s, robot, goal, yaw, DOWN, 1.0, final_tol=LOADED_TOL)

        def rise(s: ObjectCentricState) -> list[Segment]:
            goal = np.array([*xy, self.travel_z])
            return line_segments(
                s, robot, goal, yaw, DOWN, opening, spacing=0.05, final_tol=LOADED_TOL
            )

        return [carry, lower, grip_segment(opening), rise]

    def shift_base(self, state: ObjectCentricState, goal: FloatArray) -> list[SegmentSource]:
        """The drive to ``goal`` (the arm and gripper held), or nothing when the base is there."""
        if np.abs(goal - base_pose(state, self.robot)).max() < 1e-9:
            return []
        arm = arm_joints(state, self.robot)
        robot = self.robot
        return [lambda s: [drive_segment(s, robot, goal, arm, self.grip, 0.01)]]


__all__ = [
    "ARM_FEATURES",
    "ARM_SPEED",
    "BASE_FEATURES",
    "BASE_SHIFTS",
    "CHASSIS_RADIUS",
    "CLOSED",
    "CUBE_CLEARANCE",
    "DOWN",
    "GRASP_Z",
    "GRIP_STEPS",
    "HOME",
    "LOADED_TOL",
    "PITCH",
    "READY",
    "RELEASE",
    "TRAVEL_Z",
    "Dynamic3DContext",
    "Dynamic3DController",
    "FloorPickController",
    "Segment",
    "TopDownController",
    "arm_joints",
    "arm_turn",
    "base_pose",
    "chassis_clear_of_box",
    "clear_of_points",
    "drive_segment",
    "dynamic3d_model",
    "face_approach",
    "face_heading",
    "floor_points",
    "grasp_and_lift",
    "grasp_yaws",
    "grip_segment",
    "gripper_quat",
    "hand_predicates",
    "ik_near",
    "line_segments",
    "nearest_ik",
    "pick_operator",
    "pick_place_domain",
    "pinch_position",
    "place_operator",
    "placement_goal",
    "region_spot",
    "segment_point_distance",
    "segment_rect_distance",
    "top_down_yaw",
    "yaw_axes",
]
