"""The ClutteredRetrieval2D planning model: clear a way to the target block, then carry it into
the target region.

How many obstructions are in the way is part of the abstraction. For each face of the target
block the *approach corridor* is the strip in front of the face that the robot occupies while
grasping it (``2·(base_radius + CORRIDOR_MARGIN)`` = 0.22 m wide, from the face out to
``arm_length + gripper_width/2 + GRASP_GAP + base_radius + BACKOFF`` ≈ 0.41 m); a corridor that
leaves the world is unusable. The *blockers* of a face are the obstructions overlapping its
corridor plus those overlapping the target region grown by ``REGION_MARGIN`` (0.02 m; they would
keep the block out). The chosen face is the usable face with the fewest blockers (ties: the lower
face index). Removing one of its blockers to a place outside every corridor and the grown region
lowers the count by exactly one and keeps the chosen face, so operators predict the count
exactly.

Concepts:

* ``HandEmpty(robot)``; ``HoldingTgt(robot, target_block)``; ``HoldingObstruction(robot)``
  (some obstruction): held means touching the suction zone with the vacuum on.
* ``Inside(target_block, target_region)``: the env's goal test (all four corners inside).
* ``Blockers{k}()`` (0-ary, k = 0…N): the chosen face has exactly ``k`` blockers;
  ``Blocked()``: it has at least one. Counting in plain STRIPS lets picking the target require
  that none is left.

Operators (and skills):

* ``PickObstruction(?robot)``: pre {HandEmpty, Blocked}; add {HoldingObstruction}; delete
  {HandEmpty}. The skill's first parameter chooses which blocker to pick.
* ``PlaceObstruction{k}(?robot)`` (k = 1…N): pre {HoldingObstruction, Blockers{k}}; add
  {HandEmpty, Blockers{k−1}}; delete {HoldingObstruction, Blockers{k}} (and {Blocked} for k = 1).
* ``PickTgt(?robot, ?target)``: pre {HandEmpty, Blockers0}; add {HoldingTgt}; delete
  {HandEmpty}.
* ``PlaceTgt(?robot, ?target, ?region)``: pre {HoldingTgt}; add {HandEmpty, Inside}; delete
  {HoldingTgt}.

So there is one abstract plan: k × (PickObstruction, PlaceObstruction), PickTgt, PlaceTgt.

Skills move the base along a collision-free SE(2) path from OMPL's RRT-Connect (1 s per attempt,
2 attempts; collision resolution 0.01 m, π/64 rad) with the arm retracted, carrying what is held,
and set the arm in place at both ends; every step the follower takes is collision-checked before
execution. Parameters are sampled uniformly with rejection of goals that collide or miss the
skill's outcome (200 draws; 1000 for PickObstruction).

* Pick, params ``(f, t, a) ∈ [0, 1]³`` (PickObstruction: ``(c, f, t, a)``, with ``c`` choosing
  blocker ``⌊c·k⌋`` of the ``k`` in name order): face ``⌊4f⌋`` of the rectangle
  (counter-clockwise from its anchor's side); the gripper centre slides along the face by
  ``(2t − 1)·(L/2 + g/2 − SUCTION_OVERLAP)`` metres from the face's middle (L: face length,
  g: gripper height 0.07 m, overlap 0.01 m); the arm is extended to ``base_radius + a·(arm_length
  − base_radius)`` metres; the gripper's outer edge stops ``GRASP_GAP`` (0.0075 m) from the face,
  facing it; then the vacuum goes on. Rejected when the grasp pose collides or the suction zone
  would also touch another object. For the target, two thirds of the draws use the chosen face.
* PlaceTgt, params ``(u, v, w) ∈ [0, 1]³``: the block's centre goes to the region's centre plus
  ``((2u − 1)·s, (2v − 1)·s)`` in the region's frame (``s`` = half the size difference minus
  ``PLACE_MARGIN`` 0.004 m), turned to the region's heading plus ``⌊4w⌋·π/2`` rad; the robot's
  pose follows from the grasp (arm as grasped); the vacuum goes off. Rejected unless the block
  would be inside the region.
* PlaceObstruction, params ``(x, y, θ) ∈ [0, 1]³``: the base goes to those fractions of the
  world shrunk by the base radius, heading ``2πθ − π`` rad, arm retracted; the vacuum goes off.
  Rejected unless the obstruction ends outside every corridor and the grown region.

Goal: ``Inside(target_block, target_region)``.

Differences from the upstream model (HandEmpty/HoldingTgt/HoldingObstruction(robot, o)/Inside
and PickTgt/PlaceTgt/PickObstruction(robot, o)/PlaceObstruction(robot, o) over *every*
rectangle, with obstructions placed anywhere): its abstraction says nothing about which
obstructions are in the way, so with 10 or 25 obstructions the abstract plans that move the
right ones are rarely among the ten the planner tries. Naming the obstruction in the abstract
plan fixes the order of removal up front, but with 25 obstructions most blockers are buried and
only one or two can be grasped first, so here the skill's sampler chooses the blocker and the
abstraction only counts them. Obstructions overlapping the region count as blockers (upstream
would fail to place the block there), and obstructions are put down out of every corridor.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.geometry import obb_obb_overlap, obbs_from_anchor
from kinder_garden2d.kinematic2d.object_types import (
    CRV_ROBOT,
    RECTANGLE,
    TARGET_BLOCK,
    TARGET_REGION,
)
from kinder_garden2d.kinematic2d.predicates import is_inside
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import pick_operator, place_operator
from kinder_gym.models.kinematic2d.crv import (
    ARM_JOINT,
    ARM_LENGTH,
    BASE_RADIUS,
    GRIPPER_HEIGHT,
    GRIPPER_WIDTH,
    VACUUM,
    CRVCollisionChecker,
    CRVController,
    Waypoint,
    checked_waypoints,
    hand_predicates,
    robot_config,
)
from kinder_gym.motion_planning import FloatArray, params_seed, plan_se2
from kinder_gym.operators import LiftedOperator
from kinder_gym.skills import Skill, SkillFailure

#: Gap (metres) between the gripper's outer edge and the grasped face: the suction zone starts
#: 0.005 m beyond the edge and is 0.01 m deep, so it overlaps the face.
GRASP_GAP = 0.0075
#: Least overlap (metres) of the suction zone with the grasped face, along the face.
SUCTION_OVERLAP = 0.01
#: Extra half-width (metres) of an approach corridor beyond the base radius.
CORRIDOR_MARGIN = 0.01
#: How far (metres) a corridor reaches beyond the base at the longest grasp.
BACKOFF = 0.1
#: The target region grown by this much (metres) is kept free of obstructions.
REGION_MARGIN = 0.02
#: Margin (metres) of the block's corners from the region's sides when placing.
PLACE_MARGIN = 0.004
#: Draws of the obstruction-grasp sampler before it gives up.
GRASP_TRIES = 1000
#: RRT-Connect seconds per attempt, and attempts.
RRT_TIMEOUT = 1.0
RRT_ATTEMPTS = 2


@dataclass(frozen=True)
class Face:
    """A side of a rectangle: its middle, unit tangent, inward unit normal and length."""

    mid: FloatArray
    tangent: FloatArray
    inward: FloatArray
    length: float


def rectangle_faces(state: ObjectCentricState, obj: Object) -> list[Face]:
    """The four faces of a rectangle object, counter-clockwise from its anchor's side."""
    x, y, th = (state.get(obj, k) for k in ("x", "y", "theta"))
    w, h = state.get(obj, "width"), state.get(obj, "height")
    c, s = math.cos(th), math.sin(th)
    ax_w, ax_h = np.array([c, s]), np.array([-s, c])
    p0 = np.array([x, y])
    corners = [p0, p0 + w * ax_w, p0 + w * ax_w + h * ax_h, p0 + h * ax_h]
    inward = [ax_h, -ax_w, -ax_h, ax_w]
    faces = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        length = float(np.linalg.norm(b - a))
        faces.append(Face(0.5 * (a + b), (b - a) / length, inward[i], length))
    return faces


def _obbs(state: ObjectCentricState, objs: Sequence[Object]) -> FloatArray:
    v = np.array(
        [[state.get(o, k) for k in ("x", "y", "theta", "width", "height")] for o in objs]
    ).reshape(-1, 5)
    return obbs_from_anchor(v[:, 0], v[:, 1], v[:, 2], v[:, 3], v[:, 4])


@dataclass(frozen=True)
class Blockers:
    """The obstructions in the way (see the module docstring)."""

    face: int | None
    """The chosen face of the target block (None: no usable face)."""
    blocking: frozenset[Object]
    """The chosen face's blockers (and those on the region)."""
    in_the_way: frozenset[Object]
    """Obstructions in any usable corridor or on the grown region."""


def find_blockers(env: ObjectCentricEnv, state: ObjectCentricState) -> Blockers:
    """The obstructions in the way of the target block's faces and of the region."""
    target: Object = env.target_block  # type: ignore[attr-defined]
    region: Object = env.target_region  # type: ignore[attr-defined]
    obstructions: list[Object] = env.obstructions  # type: ignore[attr-defined]
    robot = state[env.robot]  # type: ignore[attr-defined]
    br, al = float(robot[BASE_RADIUS]), float(robot[ARM_LENGTH])
    reach = al + 0.5 * float(robot[GRIPPER_WIDTH]) + GRASP_GAP + br + BACKOFF
    half_w = br + CORRIDOR_MARGIN
    xmin, xmax, ymin, ymax = env.config.world_bounds  # type: ignore[attr-defined]
    rows, usable = [], []
    for side in rectangle_faces(state, target):
        out = -side.inward
        centre = side.mid + 0.5 * reach * out
        rows.append([centre[0], centre[1], out[0], out[1], 0.5 * reach, half_w])
        ends = [
            side.mid + d * out + e * side.tangent for d in (0, reach) for e in (-half_w, half_w)
        ]
        usable.append(all(xmin <= p[0] <= xmax and ymin <= p[1] <= ymax for p in ends))
    region_obb = _obbs(state, [region])
    region_obb[:, 4:] += REGION_MARGIN
    boxes = np.concatenate([np.array(rows), region_obb])
    if obstructions:
        hits = obb_obb_overlap(boxes, _obbs(state, obstructions))
    else:
        hits = np.zeros((5, 0), dtype=bool)
    on_region = {o for o, h in zip(obstructions, hits[4]) if h}
    per_face = [{o for o, h in zip(obstructions, hits[k]) if h} | on_region for k in range(4)]
    candidates = [k for k in range(4) if usable[k]]
    face = min(candidates, key=lambda k: (len(per_face[k]), k)) if candidates else None
    blocking = per_face[face] if face is not None else on_region
    in_the_way = set(on_region).union(*(per_face[k] for k in candidates))
    return Blockers(face, frozenset(blocking), frozenset(in_the_way))


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The ClutteredRetrieval2D planning model (any number of obstructions)."""
    robot_obj: Object = env.robot  # type: ignore[attr-defined]
    target: Object = env.target_block  # type: ignore[attr-defined]
    region: Object = env.target_region  # type: ignore[attr-defined]
    obstructions: list[Object] = list(env.obstructions)  # type: ignore[attr-defined]
    obstruction_set = frozenset(obstructions)
    n = len(obstructions)

    HandEmpty, HoldingTgt = hand_predicates(env, TARGET_BLOCK, "HoldingTgt")
    HoldingObstruction = Predicate(
        "HoldingObstruction",
        (CRV_ROBOT,),
        lambda s, o: bool(obstruction_set.intersection(_held(env, s.data))),
    )
    Inside = Predicate(
        "Inside", (TARGET_BLOCK, TARGET_REGION), lambda s, o: is_inside(s, o[0], o[1])
    )
    Blocked = Predicate("Blocked", (), lambda s, o: bool(find_blockers(env, s).blocking))

    def has_blockers(k: int) -> Callable[[ObjectCentricState, Sequence[Object]], bool]:
        return lambda s, o: len(find_blockers(env, s).blocking) == k

    counts = [Predicate(f"Blockers{k}", (), has_blockers(k)) for k in range(n + 1)]

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        held = _held(env, state.data)
        atoms: set[GroundAtom] = set()
        if not held:
            atoms.add(HandEmpty.ground([robot_obj]))
        if target in held:
            atoms.add(HoldingTgt.ground([robot_obj, target]))
        if obstruction_set.intersection(held):
            atoms.add(HoldingObstruction.ground([robot_obj]))
        if is_inside(state, target, region):
            atoms.add(Inside.ground([target, region]))
        k = len(find_blockers(env, state).blocking)
        atoms.add(counts[k].ground([]))
        if k:
            atoms.add(Blocked.ground([]))
        return frozenset(atoms)

    r = Variable("?robot", CRV_ROBOT)
    t = Variable("?target", TARGET_BLOCK)
    g = Variable("?region", TARGET_REGION)
    pick_obstruction = LiftedOperator(
        "PickObstruction",
        (r,),
        frozenset({HandEmpty.lift([r]), Blocked.lift([])}),
        frozenset({HoldingObstruction.lift([r])}),
        frozenset({HandEmpty.lift([r])}),
    )
    place_obstruction = [
        LiftedOperator(
            f"PlaceObstruction{k}",
            (r,),
            frozenset({HoldingObstruction.lift([r]), counts[k].lift([])}),
            frozenset({HandEmpty.lift([r]), counts[k - 1].lift([])}),
            frozenset(
                {HoldingObstruction.lift([r]), counts[k].lift([])}
                | ({Blocked.lift([])} if k == 1 else set())
            ),
        )
        for k in range(1, n + 1)
    ]
    pick_target = pick_operator(
        "PickTgt", HandEmpty, HoldingTgt, t, [counts[0].lift([])], delete_source=False
    )
    place_target = place_operator(
        "PlaceTgt", HandEmpty, HoldingTgt, t, [Inside.lift([t, g])], params=[g]
    )

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        del state
        return frozenset({Inside.ground([target, region])})

    return PlanningModel(
        name="clutteredretrieval2d",
        env=env,
        types=(CRV_ROBOT, RECTANGLE, TARGET_BLOCK, TARGET_REGION),
        predicates=(HandEmpty, HoldingTgt, HoldingObstruction, Inside, Blocked, *counts),
        skills=(
            Skill(pick_obstruction, PickObstructionController, env),
            *(Skill(op, PlaceObstructionController, env) for op in place_obstruction),
            Skill(pick_target, PickTargetController, env),
            Skill(place_target, PlaceTargetController, env),
        ),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=600,
    )


def _held(env: ObjectCentricEnv, data: FloatArray) -> list[Object]:
    return env.world.held_objects(data)  # type: ignore[attr-defined, no-any-return]


def _after(state: ObjectCentricState, data: FloatArray) -> ObjectCentricState:
    out = state.copy()
    out.data[:] = data
    return out


class _MoveController(CRVController):
    """Retract the arm, follow an RRT-Connect base path to the goal pose, set the goal arm.

    Subclasses give the goal configuration for the parameters and what it must achieve; the
    parameters are sampled by rejection. The first of ``objects`` is the robot.
    """

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    #: Vacuum setting (0 off, 1 on) while moving.
    vacuum = 0.0
    #: Rejection-sampling attempts of :meth:`sample_parameters`.
    tries = 200

    def obj(self, state: ObjectCentricState, params: FloatArray) -> Object | None:
        """The object picked or placed (default: the second of ``objects``)."""
        del state, params
        return self.objects[1]

    @abc.abstractmethod
    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        """The goal ``[x, y, theta, arm]`` for ``params`` (None: no such configuration)."""

    @abc.abstractmethod
    def goal_ok(self, state: ObjectCentricState, params: FloatArray, data: FloatArray) -> bool:
        """Whether the goal configuration (the state's data with the robot there, held objects
        carried) gives the intended outcome, besides being collision-free."""

    def draw(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """One proposal (default: uniform)."""
        return super().sample_parameters(state, rng)

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Proposals from :meth:`draw`, rejecting goals that collide or miss the outcome."""
        checker = CRVCollisionChecker(self.context.world, state)
        params = self.draw(state, rng)
        for _ in range(self.tries):
            goal = self.goal_config(state, params)
            if (
                goal is not None
                and checker(goal)
                and self.goal_ok(state, params, checker.data_at(goal))
            ):
                return params
            params = self.draw(state, rng)
        return params

    def waypoints(self, state: ObjectCentricState) -> list[Waypoint]:
        name = type(self).__name__
        env = self.context
        checker = CRVCollisionChecker(env.world, state)
        goal = self.goal_config(state, self.params)
        if goal is None:
            raise SkillFailure(f"{name}: no goal configuration for parameters {self.params}")
        if not checker(goal):
            raise SkillFailure(f"{name}: goal {goal.round(3)} is in collision")
        if not self.goal_ok(state, self.params, checker.data_at(goal)):
            raise SkillFailure(f"{name}: goal {goal.round(3)} misses the intended outcome")
        q0 = robot_config(state, self.robot)
        retracted = float(state[self.robot][BASE_RADIUS])
        start = np.array([q0[0], q0[1], q0[2], retracted])
        pre = np.array([goal[0], goal[1], goal[2], retracted])
        if not checker(start):
            raise SkillFailure(f"{name}: cannot retract the arm at {q0.round(3)}")
        if not checker(pre):
            raise SkillFailure(f"{name}: the pre-goal pose {pre.round(3)} is in collision")
        checker.arm = retracted
        xmin, xmax, ymin, ymax = env.config.world_bounds
        path3 = plan_se2(
            start[:3],
            pre[:3],
            checker,
            ((xmin + retracted, xmax - retracted), (ymin + retracted, ymax - retracted)),
            max_step=(0.01, 0.01, math.pi / 64),
            seed=params_seed(self.params, len(name)),
            timeout=RRT_TIMEOUT,
            attempts=RRT_ATTEMPTS,
        )
        if path3 is None:
            raise SkillFailure(f"{name}: no collision-free base path to {pre.round(3)}")
        path = [q0, start, *(np.array([*q[:3], retracted]) for q in path3[1:]), goal]
        high = np.asarray(env.action_space.high, dtype=np.float64)[:4]
        failure = f"{name}: an execution step collides"
        return checked_waypoints(checker, path, high, self.vacuum, failure)


class _PickController(_MoveController):
    """Face a point of one of the object's faces and switch the vacuum on."""

    vacuum = 0.0
    vacuum_after = 1.0

    def grasp_config(
        self, state: ObjectCentricState, obj: Object, f: float, t: float, a: float
    ) -> FloatArray:
        """The grasp configuration of face ``⌊4f⌋`` at ``t`` along it with arm fraction ``a``."""
        face = rectangle_faces(state, obj)[min(3, int(4 * f))]
        v = state[self.robot]
        br, al = float(v[BASE_RADIUS]), float(v[ARM_LENGTH])
        gh, gw = float(v[GRIPPER_HEIGHT]), float(v[GRIPPER_WIDTH])
        slide = max(0.0, 0.5 * face.length + 0.5 * gh - SUCTION_OVERLAP)
        point = face.mid + (2 * t - 1) * slide * face.tangent
        arm = br + a * (al - br)
        base = point - (arm + 0.5 * gw + GRASP_GAP) * face.inward
        return np.array(
            [base[0], base[1], math.atan2(face.inward[1], face.inward[0]), arm], dtype=np.float64
        )

    def goal_ok(self, state: ObjectCentricState, params: FloatArray, data: FloatArray) -> bool:
        on = data.copy()
        on[self.context.world.robot_idx[VACUUM]] = 1.0
        return _held(self.context, on) == [self.obj(state, params)]


_GRASP_DOC = (
    "face ⌊4f⌋ of the rectangle (counter-clockwise from its anchor's side); the gripper "
    "centre sits (2t − 1)·(L/2 + g/2 − 0.01) metres from the face's middle along it (L: face "
    "length, g: gripper height); the arm is extended to base_radius + a·(arm_length − "
    "base_radius) metres."
)


class PickTargetController(_PickController):
    """Grasp the target block. Objects: ``(robot, target_block)``."""

    params_doc = f"(f, t, a): {_GRASP_DOC}"

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        f, t, a = (float(p) for p in params)
        return self.grasp_config(state, self.objects[1], f, t, a)

    def draw(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, but two thirds of the draws on the chosen face."""
        params = rng.uniform(0.0, 1.0, 3)
        if rng.uniform() < 2 / 3:
            face = find_blockers(self.context, state).face
            if face is not None:
                params[0] = (face + rng.uniform(0.05, 0.95)) / 4
        return params


class PickObstructionController(_PickController):
    """Grasp one of the obstructions in the way (chosen by a parameter). Objects: ``(robot,)``."""

    params_space = spaces.Box(0.0, 1.0, (4,), dtype=np.float64)
    params_doc = (
        f"(c, f, t, a): c chooses the obstruction ⌊c·k⌋ of the k blockers in name order; "
        f"{_GRASP_DOC}"
    )

    def obj(self, state: ObjectCentricState, params: FloatArray) -> Object | None:
        blocking = sorted(find_blockers(self.context, state).blocking)
        if not blocking:
            return None
        return blocking[min(len(blocking) - 1, int(float(params[0]) * len(blocking)))]

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        obj = self.obj(state, params)
        if obj is None:
            return None
        f, t, a = (float(p) for p in params[1:])
        return self.grasp_config(state, obj, f, t, a)

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, rejecting grasps that collide or touch another object (up to ``GRASP_TRIES``
        draws: in dense clutter few grasps of few blockers are free)."""
        blocking = sorted(find_blockers(self.context, state).blocking)
        checker = CRVCollisionChecker(self.context.world, state)
        world = self.context.world
        params = rng.uniform(0.0, 1.0, 4)
        for _ in range(GRASP_TRIES):
            if not blocking:
                break
            obj = blocking[min(len(blocking) - 1, int(params[0] * len(blocking)))]
            goal = self.grasp_config(state, obj, *(float(p) for p in params[1:]))
            if checker(goal):
                data = checker.data_at(goal)
                data[world.robot_idx[VACUUM]] = 1.0
                if world.held_objects(data) == [obj]:
                    return params
            params = rng.uniform(0.0, 1.0, 4)
        return params


class _PlaceController(_MoveController):
    """Carry the held object to a goal and release it."""

    vacuum = 1.0
    vacuum_after = 0.0


class PlaceTargetController(_PlaceController):
    """Put the held target block inside the target region.

    Objects: ``(robot, target_block, target_region)``.
    """

    params_doc = (
        "(u, v, w): the block's centre goes to the region's centre plus ((2u − 1)·s, "
        "(2v − 1)·s) metres in the region's frame (s: half the size difference minus 0.004 m), "
        "turned to the region's heading plus ⌊4w⌋·π/2 radians; the arm keeps its extension."
    )

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        u, v, w = (float(p) for p in params)
        robot, block, region = self.objects
        rv = state[robot]
        th, arm, gw = float(rv[2]), float(rv[ARM_JOINT]), float(rv[GRIPPER_WIDTH])
        tip = rv[:2] + (arm + 0.5 * gw) * np.array([math.cos(th), math.sin(th)])
        bx, by, bth = (state.get(block, k) for k in ("x", "y", "theta"))
        bw, bh = state.get(block, "width"), state.get(block, "height")
        # The block's anchor in the tool-tip frame, and its heading relative to the robot's.
        c, s = math.cos(th), math.sin(th)
        d = np.array([bx, by]) - tip
        rel = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        rel_th = bth - th
        gx, gy, gth = (state.get(region, k) for k in ("x", "y", "theta"))
        gs_w, gs_h = state.get(region, "width"), state.get(region, "height")
        slack = 0.5 * min(gs_w - bw, gs_h - bh) - PLACE_MARGIN
        if slack < 0:
            return None
        gc, gsn = math.cos(gth), math.sin(gth)
        local = np.array([0.5 * gs_w + (2 * u - 1) * slack, 0.5 * gs_h + (2 * v - 1) * slack])
        centre = np.array(
            [gx + gc * local[0] - gsn * local[1], gy + gsn * local[0] + gc * local[1]]
        )
        phi = gth + min(3, int(4 * w)) * math.pi / 2
        cp, sp = math.cos(phi), math.sin(phi)
        anchor = centre - np.array([cp * 0.5 * bw - sp * 0.5 * bh, sp * 0.5 * bw + cp * 0.5 * bh])
        new_th = phi - rel_th
        cn, sn = math.cos(new_th), math.sin(new_th)
        new_tip = anchor - np.array([cn * rel[0] - sn * rel[1], sn * rel[0] + cn * rel[1]])
        base = new_tip - (arm + 0.5 * gw) * np.array([cn, sn])
        heading = (new_th + math.pi) % (2 * math.pi) - math.pi
        return np.array([base[0], base[1], heading, arm])

    def initiable(self, state: ObjectCentricState) -> bool:
        return self.objects[1] in _held(self.context, state.data)

    def goal_ok(self, state: ObjectCentricState, params: FloatArray, data: FloatArray) -> bool:
        return is_inside(_after(state, data), self.objects[1], self.objects[2])


class PlaceObstructionController(_PlaceController):
    """Put the held obstruction down out of the way. Objects: ``(robot,)``."""

    params_doc = (
        "(x, y, θ): the base goes to the fractions (x, y) of the world shrunk by the base radius "
        "(metres) with heading 2πθ − π radians, the arm retracted."
    )

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        br = float(state[self.robot][BASE_RADIUS])
        xmin, xmax, ymin, ymax = self.context.config.world_bounds
        x = xmin + br + float(params[0]) * (xmax - xmin - 2 * br)
        y = ymin + br + float(params[1]) * (ymax - ymin - 2 * br)
        return np.array([x, y, 2 * math.pi * float(params[2]) - math.pi, br])

    def obj(self, state: ObjectCentricState, params: FloatArray) -> Object | None:
        obstructions = set(self.context.obstructions)
        held = [o for o in _held(self.context, state.data) if o in obstructions]
        return held[0] if held else None

    def initiable(self, state: ObjectCentricState) -> bool:
        return self.obj(state, self.params) is not None

    def goal_ok(self, state: ObjectCentricState, params: FloatArray, data: FloatArray) -> bool:
        obj = self.obj(state, params)
        off = data.copy()
        off[self.context.world.robot_idx[VACUUM]] = 0.0
        after = find_blockers(self.context, _after(state, off))
        before = find_blockers(self.context, state)
        return obj not in after.in_the_way and after.blocking == before.blocking - {obj}


__all__: Sequence[str] = [
    "Blockers",
    "Face",
    "PickObstructionController",
    "PickTargetController",
    "PlaceObstructionController",
    "PlaceTargetController",
    "create_model",
    "find_blockers",
    "rectangle_faces",
]
