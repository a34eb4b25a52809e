"""The Transport3D planning model: pick every cube and the box off the floor onto the table.

Concepts (over the movable objects: the cubes and the box):

* ``HandEmpty(robot)`` / ``Holding(robot, object)``.
* ``OnFloor(object)``: not held, centre below 0.3 m.
* ``OnTable(object, table)``: not held, centre at 0.3 m or higher (the env's goal height).

Operators: ``Pick(?robot, ?object)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty,
OnFloor) and ``Place(?robot, ?object, ?table)`` (pre Holding; add HandEmpty, OnTable; delete
Holding). Goal: every cube and the box ``OnTable``, and ``HandEmpty``; the last Place retracts the
arm, which the env's goal also asks for (end effector 0.2 m from every object, gripper open).

Skills (all motion collision-checked with the env's own pybullet geometry; OMPL RRT-Connect for
the base in SE(2) and for the arm in joint space; IK with the robot model's mink solver):

* Pick: retract the arm, drive the base to a sampled standoff facing the object, reach a point
  above the grasp (a cube's centre, or the top of the box's nearest wall), descend, close,
  and lift back.
* Place: retract the arm (carrying the object), drive to a sampled standoff beside the table,
  reach above a sampled spot on the table, descend until the object is 3 mm above the top, open,
  lift, retract.

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import CONTAINER_MIN_HALF_EXTENT
from kinder_garden3d.kinematic3d.geometry import quat_to_matrix
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE, ROBOT_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.kinematic3d.tidybot import (
    HOME,
    ConfigChecker,
    ConfigWaypoint,
    TidyBotController,
    arm_path,
    base_path,
    config_delta,
    solve_ik,
    tool_to_pinch,
    top_down_quat,
    wrap,
)
from kinder_gym.motion_planning import FloatArray, params_seed, segment_valid
from kinder_gym.operators import GroundOperator, LiftedOperator
from kinder_gym.skills import Skill, SkillFailure

#: Height above the grasp/place pose of the pre-grasp/pre-place end-effector pose (metres).
APPROACH = 0.12
#: Centre height from which an object counts as on the table (the env's goal threshold).
TABLE_Z = 0.3
#: How far past the objects (and the robot) the base may be planned to go (metres).
PLANNING_MARGIN = 1.0


def _yaw_of(q: FloatArray) -> float:
    m = quat_to_matrix(q)
    return math.atan2(float(m[1, 0]), float(m[0, 0]))


class ReachController(TidyBotController):
    """Shared motion pieces: retract, drive, reach down, act, lift (also used by the Obstruction3D,
    Packing3D and Table3D models)."""

    def _wp(self, q: FloatArray, gripper: float = 0.0) -> ConfigWaypoint:
        return ConfigWaypoint(tuple(float(v) for v in q), gripper)

    def _sequence(
        self,
        state: ObjectCentricState,
        base_goal: FloatArray,
        ee_pos: FloatArray,
        ee_quat: FloatArray,
        gripper: float,
        salt: int,
    ) -> list[ConfigWaypoint]:
        env = self.context
        checker = ConfigChecker(env, state)
        q = np.asarray(state[self.robot][:10], dtype=np.float64)
        seed = params_seed(self.params, salt)
        wps: list[ConfigWaypoint] = []
        # 1. Retract the arm where the robot stands.
        if np.max(np.abs(config_delta(q[3:], HOME))) > 1e-6:
            path = arm_path(checker, q, HOME, seed)
            wps += [self._wp(p) for p in path]
            q = path[-1]
        # 2. Drive to the standoff.
        if np.max(np.abs(config_delta(q[:3], base_goal))) > 1e-6:
            path = base_path(checker, q, base_goal, self.planning_bounds(state), seed)
            wps += [self._wp(p) for p in path]
            q = path[-1]
        # 3. Reach above, then down (IK seeded from the retract pose, then from the approach).
        above = solve_ik(ee_pos + np.array([0.0, 0.0, APPROACH]), ee_quat, q[:3], HOME)
        at = solve_ik(ee_pos, ee_quat, q[:3], above)
        q_above = np.concatenate([q[:3], above])
        q_at = np.concatenate([q[:3], at])
        path = arm_path(checker, q, above, seed + 1)
        wps += [self._wp(p) for p in path]
        if not segment_valid(q_above, q_at, checker, np.full(10, 0.05)):
            raise SkillFailure(f"{type(self).__name__}: the final approach collides")
        wps.append(self._wp(q_at, gripper))
        # 4. Lift straight back (the env checks that move itself).
        wps.append(self._wp(q_above))
        return wps

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
    """Pick an object off the floor. Objects: ``(robot, object)``."""

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
        obj_yaw = _yaw_of(np.asarray(f[3:7]))
        half = np.asarray(f[9:12], dtype=np.float64)
        # Upstream's object_type is −1 for every cuboid; a container is what the env carries
        # things in (every half extent above CONTAINER_MIN_HALF_EXTENT).
        container = bool(np.all(half > CONTAINER_MIN_HALF_EXTENT))
        if container:  # grasp the top of the wall nearest the robot
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
        else:
            grasp = pos.copy()
            close_dir = obj_yaw
        # Fingers close along ee_yaw + π/2: across the wall for the box (two yaws), across any
        # pair of faces for a cube (four yaws); take the one closest to the approach direction.
        turns = (0, 2) if container else (0, 1, 2, 3)
        candidates = [close_dir - math.pi / 2 + k * math.pi / 2 for k in turns]
        ee_yaw = min(candidates, key=lambda y: abs(wrap(y - angle)))
        base_goal = self._standoff(state, grasp, dist, angle)
        return self._sequence(state, base_goal, grasp, top_down_quat(ee_yaw), -1.0, salt=1)


class PlaceController(ReachController):
    """Place the held object on the table. Objects: ``(robot, object, table)``."""

    params_space = spaces.Box(0.0, 1.0, (4,), dtype=np.float64)
    params_doc = (
        "(u, v, dist, side): the object's centre goes to fractions (u, v) of the table top "
        "(shrunk by the object's half extents and 2 cm), 3 mm above it; the base stands "
        "0.45 + 0.2·dist metres away, on the table's −x side (side < 1/3), −y side (< 2/3) or "
        "+y side."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "grasp_active") > 0.5

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, obj, table = self.objects
        u, v, dist_p, side = (float(p) for p in self.params)
        t = state[table]
        t_half = np.asarray(t[9:12], dtype=np.float64)
        o_half = np.asarray(state[obj][9:12], dtype=np.float64)
        r = float(np.hypot(o_half[0], o_half[1])) + 0.02
        px = t[0] - t_half[0] + r + u * max(0.0, 2 * (t_half[0] - r))
        py = t[1] - t_half[1] + r + v * max(0.0, 2 * (t_half[1] - r))
        pz = t[2] + t_half[2] + o_half[2] + 0.003
        angle = (0.0, math.pi / 2, -math.pi / 2)[min(2, int(side * 3))]
        dist = 0.45 + 0.2 * dist_p
        # The end effector points down along the approach; the object hangs below it by the
        # grasp transform, so the end effector goes where that puts the object at the spot.
        # The grasp transform is in the tool frame, a quarter turn from the pinch frame.
        tf_p = np.asarray(state[robot][12:15], dtype=np.float64)
        tool_q = top_down_quat(angle)
        tool_p = np.array([px, py, pz]) - quat_to_matrix(tool_q) @ tf_p
        ee_p, ee_q = tool_to_pinch(tool_p, tool_q)
        base_goal = self._standoff(state, np.array([px, py]), dist, angle)
        return self._sequence(state, base_goal, ee_p, ee_q, 1.0, salt=2)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Transport3D planning model (any number of cubes)."""
    robot_obj: Object = env.robot  # type: ignore[attr-defined]
    table_obj: Object = env.table  # type: ignore[attr-defined]
    cubes: list[Object] = list(env.cubes)  # type: ignore[attr-defined]
    movables = sorted([*cubes, env.box], key=lambda o: o.name)  # type: ignore[attr-defined]

    def held(s: ObjectCentricState, o: Object) -> bool:
        return s.get(o, "grasp_active") > 0.5

    HandEmpty = Predicate("HandEmpty", (ROBOT_TYPE,))
    Holding = Predicate("Holding", (ROBOT_TYPE, CUBOID_TYPE))
    OnFloor = Predicate("OnFloor", (CUBOID_TYPE,))
    OnTable = Predicate("OnTable", (CUBOID_TYPE, CUBOID_TYPE))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms: set[GroundAtom] = set()
        if state.get(robot_obj, "grasp_active") < 0.5:
            atoms.add(HandEmpty.ground([robot_obj]))
        for o in movables:
            if held(state, o):
                atoms.add(Holding.ground([robot_obj, o]))
            elif state.get(o, "pose_z") >= TABLE_Z:
                atoms.add(OnTable.ground([o, table_obj]))
            else:
                atoms.add(OnFloor.ground([o]))
        return frozenset(atoms)

    r = Variable("?robot", ROBOT_TYPE)
    o = Variable("?object", CUBOID_TYPE)
    t = Variable("?table", CUBOID_TYPE)
    pick = LiftedOperator(
        "Pick",
        (r, o),
        frozenset({HandEmpty.lift([r]), OnFloor.lift([o])}),
        frozenset({Holding.lift([r, o])}),
        frozenset({HandEmpty.lift([r]), OnFloor.lift([o])}),
    )
    place = LiftedOperator(
        "Place",
        (r, o, t),
        frozenset({Holding.lift([r, o])}),
        frozenset({HandEmpty.lift([r]), OnTable.lift([o, t])}),
        frozenset({Holding.lift([r, o])}),
    )

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        if op.objects[1] not in movables:
            return False
        return op.parent is not place or op.objects[2] == table_obj

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset(
            {HandEmpty.ground([robot_obj])} | {OnTable.ground([m, table_obj]) for m in movables}
        )

    return PlanningModel(
        name="transport3d",
        env=env,
        types=(ROBOT_TYPE, CUBOID_TYPE),
        predicates=(HandEmpty, Holding, OnFloor, OnTable),
        skills=(Skill(pick, PickController, env), Skill(place, PlaceController, env)),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=300,
        operator_filter=keep,
    )


__all__: Sequence[str] = [
    "APPROACH",
    "PickController",
    "PlaceController",
    "ReachController",
    "create_model",
    "params_seed",
]
