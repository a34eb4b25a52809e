"""The ClutteredStorage2D planning model: stand every block upright in the shelf opening.

The shelf opening (0.375 tall, 0.3175 wide per stored block) starts filled with flat blocks, one
per slot (from b3 on), so a new block fits nowhere until the stored ones are moved. The world is
kinematic (no gravity): a block stays wherever it is released. The model's strategy:

1. push every flat stored block up to the top of the opening and level it there (it stays inside
   the opening), which frees a 0.31-tall band below the stored layer;
2. pick every floor block by one of its end faces (so it lies along the arm) and insert it
   upright into that band from below, at a free x.

Upright blocks take 0.04 of width each, so the opening holds all N blocks with room to spare.

Concepts:

* ``Holding(robot, block)`` / ``HandEmpty(robot)``: the block is (nothing is) in the suction zone
  with the vacuum on.
* ``OnShelf(block, shelf)`` / ``NotOnShelf(block, shelf)``: all four corners of the block lie in
  the shelf's opening (the env's ``is_inside_shelf``).
* ``ShelfClear(shelf)`` / ``ShelfCluttered(shelf)``: no block in the opening *obstructs* (is
  not upright, i.e. more than π/8 from vertical, and reaches below the top band, i.e. its lowest
  corner is more than 0.06 m under the opening's top).

Goal: ``OnShelf(block, shelf)`` for every block.

Operators (and skills):

* ``ClearShelf(?robot, ?shelf)``: pre {HandEmpty, ShelfCluttered}; add {ShelfClear}; delete
  {ShelfCluttered}. For each obstructing block (nearest first): drive (RRT-Connect in SE(2), arm
  retracted) under it, facing its lower long face at the sampled grasp point (or the nearest one
  from which the base stays in the world and the gripper fits in the opening); extend the arm
  until the gripper is 0.015 m short of the face; vacuum on; move the block along a straight,
  levelling path (8 exact intermediate poses) until it is level with its top 0.01 m under the
  opening's top (the base keeps its height and the arm extends); vacuum off; retract the arm.
  Param: the grasp point's offset from the face's middle, in [−1, 1] × 0.06 m (shared by all
  blocks).
* ``PickFromFloor(?robot, ?block, ?shelf)``: pre {HandEmpty, NotOnShelf}; add {Holding}; delete
  {HandEmpty}. Drive (RRT-Connect, arm retracted) to face one end face of the block, extend the
  arm until the gripper is 0.015 m short of the block's nearest corner, vacuum on, retract the
  arm (the block follows). Params: (end, arm, side, tilt): end < 0.5 picks one end face, else
  the other; the arm extension is base_radius + arm·(arm_length − base_radius) metres; the
  gripper may be shifted across the face by up to ±0.05 m and turned by up to ±π/12 from the
  block's axis (to reach ends that a neighbour crowds; the sampler tries straight-on grasps on
  every other draw).
* ``PlaceInShelf(?robot, ?block, ?shelf)``: pre {Holding, NotOnShelf, ShelfClear}; add
  {HandEmpty, OnShelf}; delete {Holding, NotOnShelf}. Turn the held block vertical (robot facing
  up), drive (RRT-Connect, carrying the block) to 0.35 m below the insertion pose, move straight
  up until the block's bottom is 0.012 m above the opening's bottom, vacuum off, back off 0.05 m.
  Param: u ∈ [0, 1], the block's x across the usable part of the opening (rejection-sampled
  against collisions).

Every controller here is a :class:`~kinder_gym.models.kinematic2d.crv_script.ScriptController`
(shared with PushPullHook2D): its motions are computed in phases, each
from the state observed when the previous phase ends, and every pose the robot steps through
(the env's step bounds) is collision-checked before it is commanded. Base paths use OMPL's
RRT-Connect with 0.5 s per attempt (two attempts); a failed query is a :class:`SkillFailure`.

Differences from the upstream model: upstream has no notion of room in the shelf (its
``PlaceBlockOnShelf`` only needs the block off the shelf), so (as we read its operators) its
shortest abstract plans insert the floor blocks into an opening the stored blocks fill and cannot
be refined; making room takes a pick from the shelf, a place on the floor and a re-grasp per
stored block, found only among longer abstract plans. Upstream's place also turns blocks by
±π/2 depending on the grasp side and plans twice (below the shelf, then up into it). Here
``ShelfClear`` orders the plan (make room first), room is made without taking stored blocks out
(lifting them needs one grasp each instead of three skills), and blocks are always grasped by an
end so that they insert upright. ``ClearShelf`` is one operator for all stored blocks (a macro):
per-block lifting operators would need a "no other block obstructs" precondition, which STRIPS
cannot state per block.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.kinematic2d.object_types import CRV_ROBOT, SHELF, TARGET_BLOCK
from kinder_garden2d.kinematic2d.predicates import is_inside_shelf, rectangle_vertices
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import empty_hand_operator, pick_operator, place_operator
from kinder_gym.models.kinematic2d.crv import (
    ARM_JOINT,
    ARM_LENGTH,
    BASE_RADIUS,
    GRIPPER_HEIGHT,
    GRIPPER_WIDTH,
    CRVCollisionChecker,
    hand_predicates,
    robot_config,
)
from kinder_gym.models.kinematic2d.crv_script import (
    Dwell,
    Phase,
    ScriptController,
    ScriptItem,
    rect_frame,
    relative_pose,
    tip_for,
    with_arm,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import Skill, SkillFailure

#: Gap between the gripper's outer edge and the grasped face, as a fraction of the gripper
#: width: the suction zone spans 0.5 to 1.5 gripper widths beyond the edge.
GRASP_GAP_FRACTION = 0.75
#: Clearance (metres) of the base from the shelf strip and the walls.
BASE_MARGIN = 1e-3
#: An obstructing block is not within this angle (radians) of vertical ...
UPRIGHT_TOLERANCE = math.pi / 8
#: ... and its lowest corner is more than this (metres) under the opening's top.
TOP_BAND = 0.06
#: Clearance (metres) between a lifted block and the opening's top.
LIFT_CLEARANCE = 0.01
#: Height (metres) of an inserted block's bottom above the opening's bottom.
INSERT_CLEARANCE = 0.012
#: Distance (metres) below the insertion pose where the straight insertion starts.
INSERT_APPROACH = 0.35
#: How far (metres) the base backs off after releasing a block in the shelf.
BACK_OFF = 0.05
#: The base stays this far (metres) below the shelf strip while reaching into the opening, so
#: the retracted gripper clears the strip.
REACH_BASE_DROP = 0.03
#: Largest sampled grasp offset (metres) from the middle of a stored block's lower face.
MAX_GRASP_OFFSET = 0.06
#: Grasp points keep this distance (metres) from the ends of a stored block's lower face.
GRASP_END_MARGIN = 0.03
#: Largest sideways shift (metres) of the gripper from the middle of an end face when grasping.
MAX_GRASP_SHIFT = 0.05
#: Largest turn (radians) of the heading from a block's axis when grasping its end.
MAX_GRASP_TILT = math.pi / 12
#: Intermediate block poses on the levelling lift path.
LIFT_POSES = 8


# ---------------------------------------------------------------------------------------------
# Geometry of this env.


def _shelf_opening(state: ObjectCentricState, shelf: Object) -> tuple[float, float, float, float]:
    """``(x_min, x_max, y_min, y_max)`` of the shelf's (axis-aligned) opening."""
    x1, y1 = state.get(shelf, "x1"), state.get(shelf, "y1")
    return x1, x1 + state.get(shelf, "width1"), y1, y1 + state.get(shelf, "height1")


def _base_bounds(
    env: ObjectCentricEnv, state: ObjectCentricState, robot: Object, shelf: Object
) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where the base centre may go: the world, shrunk by the radius, below the shelf strip."""
    r = float(state[robot][BASE_RADIUS]) + BASE_MARGIN
    xmin, xmax, ymin, _ = env.config.world_bounds  # type: ignore[attr-defined]
    return (xmin + r, xmax - r), (ymin + r, state.get(shelf, "y") - r)


def is_upright(state: ObjectCentricState, block: Object) -> bool:
    """Is the block's long axis within :data:`UPRIGHT_TOLERANCE` of vertical?"""
    _, th = rect_frame(state, block)
    w, h = state.get(block, "width"), state.get(block, "height")
    axis = th if w >= h else th + math.pi / 2
    return abs(math.cos(axis)) <= math.sin(UPRIGHT_TOLERANCE)


def obstructs(state: ObjectCentricState, block: Object, shelf: Object) -> bool:
    """Does a block inside the opening take the room that upright blocks need?"""
    if not is_inside_shelf(state, block, shelf) or is_upright(state, block):
        return False
    top = _shelf_opening(state, shelf)[3]
    return float(rectangle_vertices(state, block)[:, 1].min()) < top - TOP_BAND


def _faces(state: ObjectCentricState, block: Object) -> list[tuple[FloatArray, FloatArray, float]]:
    """The block's four faces as ``(middle, inward unit normal, length)``: the two long faces
    first, then the two end faces."""
    corners = rectangle_vertices(state, block)
    centre = corners.mean(axis=0)
    out = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        mid = 0.5 * (a + b)
        n = centre - mid
        out.append((mid, n / float(np.linalg.norm(n)), float(np.linalg.norm(b - a))))
    out.sort(key=lambda f: -f[2])
    return out


def _grasp_config(
    face_point: FloatArray, inward: FloatArray, arm: float, gripper_width: float
) -> FloatArray:
    """The configuration facing ``inward`` whose gripper is the grasp gap short of
    ``face_point``."""
    reach = arm + (0.5 + GRASP_GAP_FRACTION) * gripper_width
    base = face_point - reach * inward
    return np.array([base[0], base[1], math.atan2(inward[1], inward[0]), arm])


# ---------------------------------------------------------------------------------------------
# Controllers.


class _StorageController(ScriptController):
    """Shared geometry: objects are ``(robot, ..., shelf)``."""

    @property
    def shelf(self) -> Object:
        """The shelf object."""
        return self.objects[-1]

    def bounds(self, state: ObjectCentricState) -> tuple[tuple[float, float], tuple[float, float]]:
        """The base's sampling bounds."""
        return _base_bounds(self.env, state, self.robot, self.shelf)

    def go_to(
        self, state: ObjectCentricState, goal: FloatArray, vacuum: float, salt: int
    ) -> list[ScriptItem]:
        """Retract the arm in place (if needed), drive to ``goal``'s pose with the arm retracted,
        then set the arm to ``goal``'s; every motion checked."""
        checker = self.checker(state)
        start = robot_config(state, self.robot)
        retracted = float(state[self.robot][BASE_RADIUS])
        items: list[ScriptItem] = []
        if abs(start[3] - retracted) > 1e-9:
            items += self.checked(checker, [start, with_arm(start, retracted)], vacuum, "retract")
            start = with_arm(start, retracted)
        pre = with_arm(goal, retracted)
        items += self.base_path(checker, start, pre, self.bounds(state), vacuum, salt)
        if abs(goal[3] - retracted) > 1e-9:
            items += self.checked(checker, [pre, goal], vacuum, "the arm extension")
        return items


class ClearShelfController(_StorageController):
    """Lift every obstructing block to the top of the opening, level. Objects: ``(robot,
    shelf)``."""

    params_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float64)
    params_doc = (
        "(offset,): the grasp point on each block's lower long face is offset·0.06 metres from "
        "the face's middle."
    )

    def phases(self, state: ObjectCentricState) -> list[Phase]:
        rx = state.get(self.robot, "x")
        blocks = [b for b in state.get_objects(TARGET_BLOCK) if obstructs(state, b, self.shelf)]
        if not blocks:
            raise SkillFailure("ClearShelf: no block obstructs the shelf")
        # Nearest end first, then along the shelf.
        blocks.sort(key=lambda b: rect_frame(state, b)[0][0])
        if abs(rect_frame(state, blocks[-1])[0][0] - rx) < abs(
            rect_frame(state, blocks[0])[0][0] - rx
        ):
            blocks.reverse()
        out: list[Phase] = []
        for k, b in enumerate(blocks):
            out += [self._approach(b, k), self._lift(b), self._retract]
        return out

    def _approach(self, block: Object, k: int) -> Phase:
        def phase(state: ObjectCentricState) -> list[ScriptItem]:
            v = state[self.robot]
            gw = float(v[GRIPPER_WIDTH])
            longs = _faces(state, block)[:2]
            mid, inward, length = min(longs, key=lambda f: float(f[0][1]))
            if inward[1] <= 0.5:
                raise SkillFailure(f"ClearShelf: {block.name}'s lower face does not face down")
            tangent = np.array([inward[1], -inward[0]])
            # The base as high as it may go: the shortest reach into the opening.
            (_, _), (_, y_top) = self.bounds(state)
            base_y = y_top - REACH_BASE_DROP
            heading = math.atan2(inward[1], inward[0])
            tip_to_face = (0.5 + GRASP_GAP_FRACTION) * gw
            x_min, x_max, _, _ = _shelf_opening(state, self.shelf)
            half_gripper = 0.5 * float(v[GRIPPER_HEIGHT])
            # The sampled offset first, then the others nearest to it: near the world's edge
            # the base cannot stand under the middle of the block.
            limit = 0.5 * length - GRASP_END_MARGIN
            preferred = float(self.params[0]) * min(MAX_GRASP_OFFSET, limit)
            candidates = sorted(np.linspace(-limit, limit, 21), key=lambda o: abs(o - preferred))
            for offset in [preferred, *candidates]:
                point = mid + offset * tangent
                arm = (point[1] - base_y) / math.sin(heading) - tip_to_face
                arm = max(arm, float(v[BASE_RADIUS]))
                goal = _grasp_config(point, inward, arm, gw)
                # The gripper enters the opening, so it must fit between the bookends.
                fits = x_min <= point[0] - half_gripper and point[0] + half_gripper <= x_max
                if fits and self.in_bounds(state, goal):
                    break
            else:
                raise SkillFailure(f"ClearShelf: cannot reach under {block.name}")
            return [*self.go_to(state, goal, 0.0, salt=11 + k), Dwell(1.0)]

        return phase

    def _lift(self, block: Object) -> Phase:
        def phase(state: ObjectCentricState) -> list[ScriptItem]:
            if self.held(state) != [block]:
                raise SkillFailure(f"ClearShelf: not holding exactly {block.name}")
            v = state[self.robot]
            gw = float(v[GRIPPER_WIDTH])
            q0 = robot_config(state, self.robot)
            centre, th = rect_frame(state, block)
            rel, rel_th = relative_pose(state, self.robot, centre, th)
            level = th - math.remainder(th, math.pi)
            top = _shelf_opening(state, self.shelf)[3]
            half = 0.5 * min(state.get(block, "width"), state.get(block, "height"))
            goal_c = np.array([centre[0], top - LIFT_CLEARANCE - half])
            configs = [q0]
            for k in range(1, LIFT_POSES + 1):
                t = k / LIFT_POSES
                c = centre + t * (goal_c - centre)
                heading = th + t * (level - th) - rel_th
                tip = tip_for(c, heading, rel)
                arm = (tip[1] - q0[1]) / math.sin(heading) - 0.5 * gw
                base = tip - (arm + 0.5 * gw) * np.array([math.cos(heading), math.sin(heading)])
                q = np.array([base[0], base[1], heading, arm])
                if not self.in_bounds(state, q):
                    raise SkillFailure(f"ClearShelf: the lift of {block.name} is out of reach")
                configs.append(q)
            return [*self.checked(self.checker(state), configs, 1.0, "the lift"), Dwell(0.0)]

        return phase

    def _retract(self, state: ObjectCentricState) -> list[ScriptItem]:
        q = robot_config(state, self.robot)
        retracted = with_arm(q, float(state[self.robot][BASE_RADIUS]))
        return self.checked(self.checker(state), [q, retracted], 0.0, "the retraction")


class PickFromFloorController(_StorageController):
    """Grasp a block by one end face and pull it in. Objects: ``(robot, block, shelf)``."""

    params_space = spaces.Box(0.0, 1.0, (4,), dtype=np.float64)
    params_doc = (
        "(end, arm, side, tilt): end < 0.5 grasps one end face, else the other; the arm "
        "extension at the grasp is base_radius + arm·(arm_length − base_radius) metres; the "
        "gripper is shifted across the face by (2·side − 1)·0.05 metres and the heading turned "
        "by (2·tilt − 1)·π/12 radians from the block's axis (side = tilt = 0.5: straight on)."
    )
    tries = 60

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray:
        """The grasp configuration for ``params``: the gripper's outer edge is the grasp gap short
        of the block's nearest corner along the heading."""
        v = state[self.robot]
        br, al, gw = float(v[BASE_RADIUS]), float(v[ARM_LENGTH]), float(v[GRIPPER_WIDTH])
        block = self.objects[1]
        mid, inward, _ = _faces(state, block)[2 + int(params[0] >= 0.5)]
        turn = (2.0 * float(params[3]) - 1.0) * MAX_GRASP_TILT
        c, s = math.cos(turn), math.sin(turn)
        u = np.array([c * inward[0] - s * inward[1], s * inward[0] + c * inward[1]])
        across = np.array([-u[1], u[0]])
        ahead = float(np.min((rectangle_vertices(state, block) - mid) @ u))
        gap = GRASP_GAP_FRACTION * gw
        side = (2.0 * float(params[2]) - 1.0) * MAX_GRASP_SHIFT
        tip = mid + (ahead - gap) * u + side * across
        arm = br + float(params[1]) * (al - br)
        base = tip - (arm + 0.5 * gw) * u
        return np.array([base[0], base[1], math.atan2(u[1], u[0]), arm])

    def _feasible(
        self, state: ObjectCentricState, checker: CRVCollisionChecker, p: FloatArray
    ) -> bool:
        goal = self.goal_config(state, p)
        pre = with_arm(goal, float(state[self.robot][BASE_RADIUS]))
        if not (self.in_bounds(state, goal) and checker(goal) and checker(pre)):
            return False
        try:
            self.checked(checker, [pre, goal], 0.0, "the arm extension")
        except SkillFailure:
            return False
        return True

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """End and arm uniform; every other draw grasps straight on, the others with a uniform
        shift and tilt; rejecting grasps whose base is out of bounds or whose approach (the
        pose, the arm's extension from the retracted pose) collides."""
        checker = self.checker(state)
        params = rng.uniform(0.0, 1.0, 4)
        for k in range(self.tries):
            if k % 2 == 0:
                params[2:] = 0.5
            if self._feasible(state, checker, params):
                break
            params = rng.uniform(0.0, 1.0, 4)
        return params

    def initiable(self, state: ObjectCentricState) -> bool:
        return not self.held(state)

    def phases(self, state: ObjectCentricState) -> list[Phase]:
        def approach(s: ObjectCentricState) -> list[ScriptItem]:
            goal = self.goal_config(s, self.params)
            if not self.in_bounds(s, goal):
                raise SkillFailure("PickFromFloor: the grasp pose is out of bounds")
            return [*self.go_to(s, goal, 0.0, salt=1), Dwell(1.0)]

        def pull(s: ObjectCentricState) -> list[ScriptItem]:
            if self.held(s) != [self.objects[1]]:
                raise SkillFailure(f"PickFromFloor: not holding exactly {self.objects[1].name}")
            q = robot_config(s, self.robot)
            retracted = with_arm(q, float(s[self.robot][BASE_RADIUS]))
            return self.checked(self.checker(s), [q, retracted], 1.0, "pulling the block in")

        return [approach, pull]


class PlaceInShelfController(_StorageController):
    """Insert the held block upright into the opening from below. Objects: ``(robot, block,
    shelf)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = (
        "(u,): the block's centre x is at fraction u of the usable width of the opening (where "
        "the block stays inside it and the base inside the world)."
    )
    tries = 50

    def initiable(self, state: ObjectCentricState) -> bool:
        return self.held(state) == [self.objects[1]]

    def place_config(self, state: ObjectCentricState, u: float) -> FloatArray | None:
        """The configuration that puts the held block upright in the opening at ``u`` (None when
        the block is not held along the arm or the base would leave its bounds)."""
        block = self.objects[1]
        v = state[self.robot]
        gw = float(v[GRIPPER_WIDTH])
        centre, th = rect_frame(state, block)
        rel, rel_th = relative_pose(state, self.robot, centre, th)
        w, h = state.get(block, "width"), state.get(block, "height")
        long_axis = rel_th if w >= h else rel_th + math.pi / 2
        # The heading that makes the block's long axis vertical.
        heading = math.pi / 2 - math.remainder(long_axis, math.pi)
        if abs(heading - math.pi / 2) > math.pi / 4:
            return None  # held by a long face: it cannot stand upright above the gripper
        length, thick = max(w, h), min(w, h)
        x_min, x_max, y_min, _ = _shelf_opening(state, self.shelf)
        lo, hi = x_min + thick, x_max - thick
        x = lo + u * (hi - lo)
        c = np.array([x, y_min + INSERT_CLEARANCE + 0.5 * length])
        tip = tip_for(c, heading, rel)
        arm = float(v[ARM_JOINT])
        base = tip - (arm + 0.5 * gw) * np.array([math.cos(heading), math.sin(heading)])
        q = np.array([base[0], base[1], heading, arm])
        return q if self.in_bounds(state, q) else None

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, rejecting insertions that collide (end pose or the straight way in)."""
        checker = self.checker(state)
        params = rng.uniform(0.0, 1.0, 1)
        for _ in range(self.tries):
            q = self.place_config(state, float(params[0]))
            if q is not None and checker(q):
                pre = q.copy()
                pre[1] -= INSERT_APPROACH
                try:
                    self.checked(checker, [pre, q], 1.0, "the insertion")
                    if checker(pre):
                        return params
                except SkillFailure:
                    pass
            params = rng.uniform(0.0, 1.0, 1)
        return params

    def phases(self, state: ObjectCentricState) -> list[Phase]:
        def insert(s: ObjectCentricState) -> list[ScriptItem]:
            q = self.place_config(s, float(self.params[0]))
            if q is None:
                raise SkillFailure("PlaceInShelf: the insertion pose is out of bounds")
            checker = self.checker(s)
            start = robot_config(s, self.robot)
            pre = q.copy()
            pre[1] -= INSERT_APPROACH
            items = self.base_path(checker, start, pre, self.bounds(s), 1.0, salt=2)
            items += self.checked(checker, [pre, q], 1.0, "the insertion")
            return [*items, Dwell(0.0)]

        def back_off(s: ObjectCentricState) -> list[ScriptItem]:
            q = robot_config(s, self.robot)
            away = q.copy()
            away[1] -= BACK_OFF
            return self.checked(self.checker(s), [q, away], 0.0, "backing off")

        return [insert, back_off]


# ---------------------------------------------------------------------------------------------
# The model.


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The ClutteredStorage2D planning model (any number of blocks)."""

    def clear(state: ObjectCentricState, shelf: Object) -> bool:
        return not any(obstructs(state, b, shelf) for b in state.get_objects(TARGET_BLOCK))

    HandEmpty, Holding = hand_predicates(env, TARGET_BLOCK)
    OnShelf = Predicate(
        "OnShelf", (TARGET_BLOCK, SHELF), lambda s, o: is_inside_shelf(s, o[0], o[1])
    )
    NotOnShelf = Predicate(
        "NotOnShelf", (TARGET_BLOCK, SHELF), lambda s, o: not is_inside_shelf(s, o[0], o[1])
    )
    ShelfClear = Predicate("ShelfClear", (SHELF,), lambda s, o: clear(s, o[0]))
    ShelfCluttered = Predicate("ShelfCluttered", (SHELF,), lambda s, o: not clear(s, o[0]))

    b = Variable("?block", TARGET_BLOCK)
    sh = Variable("?shelf", SHELF)
    cluttered = [ShelfCluttered.lift([sh])]
    clear_shelf = empty_hand_operator(
        "ClearShelf", HandEmpty, [sh], cluttered, [ShelfClear.lift([sh])], cluttered
    )
    pick = pick_operator(
        "PickFromFloor",
        HandEmpty,
        Holding,
        b,
        [NotOnShelf.lift([b, sh])],
        params=[sh],
        delete_source=False,
    )
    place = place_operator(
        "PlaceInShelf",
        HandEmpty,
        Holding,
        b,
        [OnShelf.lift([b, sh])],
        also_need=[NotOnShelf.lift([b, sh]), ShelfClear.lift([sh])],
        params=[sh],
        also_delete=[NotOnShelf.lift([b, sh])],
    )

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        shelf = state.get_objects(SHELF)[0]
        return frozenset(OnShelf.ground([b, shelf]) for b in state.get_objects(TARGET_BLOCK))

    return PlanningModel(
        name="clutteredstorage2d",
        env=env,
        types=(CRV_ROBOT, TARGET_BLOCK, SHELF),
        predicates=(Holding, HandEmpty, OnShelf, NotOnShelf, ShelfClear, ShelfCluttered),
        skills=(
            Skill(clear_shelf, ClearShelfController, env),
            Skill(pick, PickFromFloorController, env),
            Skill(place, PlaceInShelfController, env),
        ),
        goal_fn=goal,
        max_skill_horizon=1000,
    )


__all__: Sequence[str] = [
    "ClearShelfController",
    "PickFromFloorController",
    "PlaceInShelfController",
    "create_model",
    "obstructs",
]
