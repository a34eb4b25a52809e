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
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TypeAlias

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden3d.robot.description import (
    RETRACT,
    forward_kinematics,
    matrix_to_quat_xyzw,
    robot_description,
)
from kinder_garden3d.robot.ik import InverseKinematics
from kinder_gym.motion_planning import FloatArray, wrap_angle
from kinder_gym.skills import Controller, SkillFailure

#: The retracted arm (the env's start pose), carried while the base drives.
HOME = np.array(RETRACT, dtype=np.float64)
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


def drive_segment(
    state: ObjectCentricState,
    robot: Object,
    goal: FloatArray,
    arm: FloatArray,
    gripper: float,
    tol: float,
) -> Segment:
    """A segment driving the base to ``goal`` ``(x, y, yaw)`` with the arm held at ``arm``,
    with a step budget of the larger of the distance and the turn at full speed, plus 40."""
    start = base_pose(state, robot)
    dist = float(np.linalg.norm(goal[:2] - start[:2]))
    turn = abs(wrap_angle(float(goal[2] - start[2])))
    steps = math.ceil(max(dist, turn) / MAX_DELTA) + 40
    return Segment(
        base=(float(goal[0]), float(goal[1]), float(goal[2])),
        arm=tuple(float(v) for v in arm),
        gripper=gripper,
        arm_tol=0.05,
        base_tol=tol,
        max_steps=steps,
    )


def drive_reach_segment(
    state: ObjectCentricState,
    robot: Object,
    goal: FloatArray,
    arm: FloatArray,
    gripper: float,
    tol: float,
) -> Segment:
    """:func:`drive_segment` for an arm that moves to ``arm`` while the base drives: its step
    budget also covers the arm's largest joint turn at :data:`ARM_SPEED`, plus 40."""
    seg = drive_segment(state, robot, goal, arm, gripper, tol)
    steps = math.ceil(arm_turn(arm_joints(state, robot), arm) / ARM_SPEED) + 40
    return replace(seg, max_steps=max(seg.max_steps, steps))


class Dynamic3DController(Controller):
    """Segment following for the Dynamic3D robot (see the module docstring).

    The context is the env. Subclasses implement :meth:`plan`; the first object is the robot.
    """

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


__all__ = [
    "ARM_FEATURES",
    "ARM_SPEED",
    "BASE_FEATURES",
    "HOME",
    "Dynamic3DController",
    "Segment",
    "arm_joints",
    "arm_turn",
    "base_pose",
    "drive_reach_segment",
    "drive_segment",
    "gripper_quat",
    "ik_near",
    "line_segments",
    "nearest_ik",
    "pinch_position",
]
