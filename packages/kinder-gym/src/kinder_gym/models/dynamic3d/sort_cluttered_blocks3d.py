"""The SortClutteredBlocks3D planning model: sort a pile of small blocks into containers by colour.

Covers the table variants (o4 and o20 into bins, o20 into bowls): a pile of 2 cm cubes lies
at the centre of a 1.2 x 0.6 m table (turned 90°, as upstream's), with four containers around
it; each cube's goal region is read from the task file (so the colour cycle is not
hard-coded): a box in its bin's frame, or, as upstream's bowl goals, a 10 cm square of the
table with its bowl's centre in it. The o12 cupboard variant (nine cubes and three rods from
the floor onto four cupboard levels) has its own model,
:mod:`kinder_gym.models.dynamic3d.sort_cupboard3d`, which :func:`create_model` returns for it.

Concepts:

* ``HandEmpty(robot)``: the fingers are open (measured closure below 0.2).
* ``Holding(robot, cube)``: the fingers are closed, the cube is within 4 cm of the pinch point
  and at least 1.5 cm above the table top.
* ``Loose(cube)``: not held and not in its goal region.
* ``Sorted(cube)``: not held and in its goal region (the env's own ``on`` test).

Operators: ``Pick(?robot, ?cube)`` (pre HandEmpty, Loose; add Holding; delete HandEmpty, Loose)
and ``Drop(?robot, ?cube)`` (pre Holding; add HandEmpty, Sorted; delete Holding). Goal: every
cube Sorted, and HandEmpty.

Skills (targets tracked closed-loop by :mod:`kinder_gym.models.dynamic3d.tidybot`; the top-down
moves are the robot's :class:`~kinder_gym.models.dynamic3d.tidybot.TopDownController`):

* Pick: the first time, retract the arm and drive the base beside the table's long side,
  facing it (straight there from upstream's start on that side, or in two straight legs
  around the table's corner from elsewhere), from where the pile and every
  container are within the arm's top-down workspace. Then move the pinch point above the cube
  with the fingers across one of its faces and opened only 7 mm wider than the cube (wide
  open, they would sweep the cube's neighbours in), descend straight until the pad tips are
  3 mm above the cube's bottom (on the table, or on the cube it is stacked on), close and lift
  straight up. The pinch point is shifted up to half the cube's width off its centre along
  the pads' width when that keeps another cube's centre out from between the pads (cubes below
  the pad tips do not count); a pick with no such shift fails at once (the planner then tries
  another heading or another order: a cube stacked on another is picked first).
* Drop: carry the cube straight above a sampled spot of its goal region (into a bowl: a spot
  within 2 cm of the bowl's centre, kept inside the square), lower it until its bottom is 1 cm
  above the container's floor or 2 cm below its rim, whichever is higher, open the fingers to
  4.7 cm (inside a bin's 8 cm), rise, and open fully.

Parameter spaces: Pick ``(rank,)`` in [0, 1]: the gripper heading among the cube's four face
headings (sorted by closeness to the base's heading; ``rank`` < 0.5 the closest, else the
second closest). Drop ``(u, v)`` in [0, 1]²: the cube's spot in its goal box, shrunk by 1 cm
on every side (world-aligned, metres, from the box's low to high corner); into a bowl, the
spot at ``(u, v)`` of the 4 cm square around the bowl's centre.

Differences from upstream: no upstream bilevel-planning model exists for this family
(baselines.md); this one is new.

Limits:

* The o20 variants need about 2,100–2,200 actions (one pick and drop takes about 100 steps
  with this arm's 0.1 rad per step joint moves), more than the 1000 every Dynamic3D id had, so
  their limit is 3500 (``benchmarks/results/step_limits.md``: 1.5 × the most actions the skills
  took planner-free, rounded up to 500; upstream registers no limit). The planner's 60 s
  budget still binds: a step simulates in 30–40 ms, so 2,100 steps cost over 60 s to sample
  once, and BP does not solve o20 in time.
* o20 into bowls (upstream's layout: bowls in table squares, 2 cm blocks) is solved in 0 of 5
  development episodes (seed 1000, as before the layout changed): four planning timeouts, and
  once all ten abstract plans failed within a second (90 skill samples failing at once). In
  a pile of twenty 2 cm blocks, seed 1001 has nine blocks resting on others, and a pick moves
  its neighbours (one slid off one block onto another): stacking predicates (``On``,
  ``Clear``) tried for the pick's precondition changed under such moves, and the exact match
  of predicted abstract states rejected the picks, so they are not in the model.
* A cube lying on an edge (tilted in the pile) is grasped as if flat; cubes whose neighbours
  get caught between the pads make the pick's prediction fail and the planner resample.
* o12 (cupboard): see :mod:`kinder_gym.models.dynamic3d.sort_cupboard3d`.
* With upstream's 2 cm blocks dropped into the 7 cm pile, blocks often lie on one another: BP
  on development seed 1000 solves 2 of 5 o4 episodes (5 of 5 with the earlier 1 cm blocks;
  ``kinder bench run -a bilevel_planning --seeds 1000 --episodes 5``). The failures were
  planning timeouts; in the one examined the abstract plan picks a covered block before the
  one on top of it, and with no stacking predicate in the model, refinement backtracks through
  the earlier steps' samples instead of reordering.

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.geometry import quat_yaw
from kinder_garden3d.dynamic3d.object_types import MOVABLE_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic3d import sort_cupboard3d
from kinder_gym.models.dynamic3d.tidybot import (
    HOME,
    RELEASE,
    Dynamic3DContext,
    SegmentSource,
    TopDownController,
    arm_joints,
    base_pose,
    drive_segment,
    dynamic3d_model,
    grasp_yaws,
    grip_segment,
    hand_predicates,
    hand_state,
    pick_operator,
    place_operator,
    placement_goal,
    region_spot,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import SkillFailure

TABLE = "table_1"
#: Gap (m) between the chassis (0.4 m square) and the table's long side at the work pose.
TABLE_GAP = 0.03
#: Distance (m) of the drive's corner waypoint beyond the table's short side.
CORNER_CLEARANCE = 0.3
#: Pinch height (m) above the table top while moving between the pile and the containers.
TRAVEL_ABOVE = 0.15
#: Gap (m) between a cube's faces and the pads while reaching around it (7 mm in all).
PRE_GRASP_GAP = 0.007
#: Pad separation (m) of the fully open gripper (the command is 1 − separation / this).
GRIPPER_OPEN = 0.085
#: Half-width (m) of a pad across the closing direction, and its thickness along it.
PAD_HALF_WIDTH = 0.011
PAD_THICKNESS = 0.009
#: Offsets of the pinch point from a cube's centre along the pads' width, as fractions of the
#: cube's width, tried in order to keep a neighbour out of the grasp (the pads are 2.2 cm wide:
#: half a 2 cm cube's width off its centre, they still cover half of it).
GRASP_SHIFTS = (0.0, 0.25, -0.25, 0.5, -0.5)
#: Pad tips reach 2.5 cm beyond the pinch point; they stop this high (m) above the table.
PAD_REACH = 0.025
PAD_CLEARANCE = 0.003
#: Height (m) of a dropped cube's bottom above its container's floor when the hand opens ...
DROP_GAP = 0.01
#: ... or, in a deep container, its depth (m) below the rim: the hand stays above upstream's
#: 10 cm deep bins (lowered to their floor, the fingers met the walls and the drop failed).
RIM_DEPTH = 0.02
#: Goal boxes are shrunk by this much (m) on every side when a drop spot is drawn.
SPOT_MARGIN = 0.01
#: Distance (m) from the pinch point within which a lifted cube counts as held.
HOLD_RADIUS = 0.04
#: Half-side (m) of the square around a bowl's centre where a cube is dropped into it.
BOWL_SPOT = 0.02


@dataclass(frozen=True)
class SortContext(Dynamic3DContext):
    """What the SortClutteredBlocks3D controllers need besides the state."""

    table: Object
    #: Goal region of each cube, by cube name.
    regions: dict[str, str]
    #: The container each goal region belongs to, by region name: the region's target (a bin)
    #: or, for a region on the table (upstream's bowl goals are table squares), the bowl
    #: dropped into it.
    containers: dict[str, Object]


class _Table:
    """The table's top height and the work pose beside its long side (the one on the table's
    local -y side), in world coordinates whatever the table's yaw."""

    def __init__(self, ctx: SortContext, state: ObjectCentricState) -> None:
        params = ctx.env.task.fixtures[ctx.table.name].params  # type: ignore[attr-defined]
        self.top = float(params["height"])
        self.centre = np.array([state.get(ctx.table, "x"), state.get(ctx.table, "y")])
        self.yaw = quat_yaw(np.asarray(state[ctx.table][3:7]))
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        self.rot = np.array([[c, -s], [s, c]])  # table frame -> world
        length, width = float(params["length"]), float(params["width"])
        self.work_local = np.array([0.0, -width / 2 - 0.2 - TABLE_GAP])
        self.work = self.world(self.work_local)
        #: Facing the table across its long side.
        self.heading = self.yaw + math.pi / 2
        self.corner_local_x = length / 2 + 0.2 + CORNER_CLEARANCE

    def world(self, local: FloatArray) -> FloatArray:
        """A point of the table's frame (x, y) in world coordinates."""
        return np.asarray(self.centre + self.rot @ local, dtype=np.float64)

    def local(self, world: FloatArray) -> FloatArray:
        """A world point (x, y) in the table's frame."""
        return np.asarray(self.rot.T @ (np.asarray(world) - self.centre), dtype=np.float64)


def _pre_grasp(state: ObjectCentricState, cube: Object) -> float:
    """Gripper command that opens the pads :data:`PRE_GRASP_GAP` wider than ``cube``."""
    return 1.0 - (state.get(cube, "bb_x") + PRE_GRASP_GAP) / GRIPPER_OPEN


def _bottom(state: ObjectCentricState, cube: Object) -> float:
    """Height (m) of a (flat) cube's bottom face."""
    return state.get(cube, "z") - 0.5 * state.get(cube, "bb_z")


def _pads_clear(
    ctx: SortContext, state: ObjectCentricState, cube: Object, yaw: float, shift: float = 0.0
) -> bool:
    """Whether the pads, opened to the pre-grasp width around ``cube`` at gripper heading
    ``yaw`` with the pinch point ``shift`` metres off the cube's centre along the pads' width,
    close on ``cube`` alone: no other cube's centre lies between them. (A neighbour partly
    under a pad is pushed aside in most seeded trials; when it is not, the prediction fails
    and the planner resamples.)"""
    across = np.array([-math.sin(yaw), math.cos(yaw)])  # the closing direction
    along = np.array([math.cos(yaw), math.sin(yaw)])
    pinch = np.array([state.get(cube, "x"), state.get(cube, "y")]) + shift * along
    inner = 0.5 * (state.get(cube, "bb_x") + PRE_GRASP_GAP)
    pad_bottom = _bottom(state, cube) + PAD_CLEARANCE
    for name in ctx.regions:
        other = ctx.env.objects[name]  # type: ignore[attr-defined]
        if other == cube or _bottom(state, other) + state.get(other, "bb_z") < pad_bottom:
            continue  # the target itself, or a cube the pads stay above (one under it)
        d = np.array([state.get(other, "x"), state.get(other, "y")]) - pinch
        half = 0.5 * state.get(other, "bb_x")
        u, w = abs(float(d @ across)), abs(float(d @ along))
        if u < inner and w < PAD_HALF_WIDTH + half:
            return False  # its centre is between the pads: it would be grasped too
    return True


def _grasp_shift(
    ctx: SortContext, state: ObjectCentricState, cube: Object, yaw: float
) -> float | None:
    """The first offset (m) of :data:`GRASP_SHIFTS` for which the pads close on ``cube``
    alone."""
    for fraction in GRASP_SHIFTS:
        shift = fraction * state.get(cube, "bb_x")
        if _pads_clear(ctx, state, cube, yaw, shift):
            return shift
    return None


class _SortController(TopDownController):
    travel_z = 0.0  # set from the table in plan()


class PickController(_SortController):
    """Pick a cube off the table (driving to the work pose first). Objects: ``(robot, cube)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = (
        "(rank,): the gripper heading closing across the cube's faces, the one closest to the "
        "base's heading when rank < 0.5, else the second closest."
    )

    hand_must_be = "open"

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform over the headings whose pads land clear of the other cubes (both when
        neither or both do)."""
        cube = self.objects[1]
        heading = self._heading(state)
        clear = [
            _grasp_shift(self.context, state, cube, yaw) is not None
            for yaw in grasp_yaws(state, cube, heading)[:2]
        ]
        if clear[0] == clear[1]:
            return rng.uniform(0.0, 1.0, 1)
        return rng.uniform(0.0, 0.5, 1) if clear[0] else rng.uniform(0.5, 1.0, 1)

    def _heading(self, state: ObjectCentricState) -> float:
        """The base's heading at the grasp (the work pose's when the base must drive)."""
        table = _Table(self.context, state)
        base = base_pose(state, self.robot)
        return float(base[2]) if np.abs(base[:2] - table.work).max() <= 0.03 else table.heading

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        ctx: SortContext = self.context
        robot, cube = self.objects
        table = _Table(ctx, state)
        self.travel_z = table.top + TRAVEL_ABOVE
        pre_grasp = _pre_grasp(state, cube)
        self.grip = pre_grasp
        plan: list[SegmentSource] = []
        base = base_pose(state, robot)
        work = np.array([*table.work, table.heading])
        if np.abs(base[:2] - work[:2]).max() > 0.03:
            if np.abs(arm_joints(state, robot) - HOME).max() > 0.05:
                raise SkillFailure("Pick: the base must drive but the arm is not retracted")
            here = table.local(base[:2])
            if here[1] > table.work_local[1] + 0.05:
                # Around the table's corner: along the long side's line from beyond its end.
                x = max(float(here[0]), table.corner_local_x)
                corner = np.array([*table.world(np.array([x, table.work_local[1]])), work[2]])
                plan.append(lambda s: [drive_segment(s, robot, corner, HOME, 0.0, 0.03)])
            plan.append(lambda s: [drive_segment(s, robot, work, HOME, 0.0, 0.01)])
            heading = float(work[2])
        else:
            heading = float(base[2])
        c = np.array([state.get(cube, f) for f in ("x", "y", "z")])
        yaw = grasp_yaws(state, cube, heading)[0 if self.params[0] < 0.5 else 1]
        shift = _grasp_shift(ctx, state, cube, yaw)
        if shift is None:
            raise SkillFailure(f"Pick: another cube lies between the pads around {cube}")
        c[:2] += shift * np.array([math.cos(yaw), math.sin(yaw)])
        grasp_z = _bottom(state, cube) + PAD_REACH + PAD_CLEARANCE

        plan += self.grasp_from_above(c[:2], grasp_z, yaw, pre_grasp, spacing=0.04)
        return plan


class DropController(_SortController):
    """Put the held cube into its container. Objects: ``(robot, cube)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(u, v): the cube's centre at fractions (u, v) of the x and y extents of its goal box "
        "(shrunk by 1 cm on every side)."
    )

    hand_must_be = "closed"

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        ctx: SortContext = self.context
        cube = self.objects[1]
        table = _Table(ctx, state)
        self.travel_z = table.top + TRAVEL_ABOVE
        self.grip = 1.0
        region = ctx.regions[cube.name]
        u, v = (float(p) for p in self.params[:2])
        spot = region_spot(ctx.env, state, region, 0, u, v, SPOT_MARGIN)
        container = ctx.containers[region]
        if ctx.env.task.regions[region].target != container.name:  # type: ignore[attr-defined]
            # A table square with a bowl in it: into the bowl, near its centre, and within the
            # square (a bowl's centre lies in its square, its rim beyond it).
            lo = region_spot(ctx.env, state, region, 0, 0.0, 0.0, SPOT_MARGIN)
            hi = region_spot(ctx.env, state, region, 0, 1.0, 1.0, SPOT_MARGIN)
            centre = np.array([state.get(container, "x"), state.get(container, "y")])
            near = centre + (np.array([u, v]) - 0.5) * 2.0 * BOWL_SPOT
            spot = np.clip(near, np.minimum(lo, hi), np.maximum(lo, hi))
        # The container's lowest point (its frame may be its bottom face), and a 5 mm floor.
        lowest = state.get(container, "z") - ctx.env.scene.objects[container.name].bottom  # type: ignore[attr-defined]
        floor = lowest + 0.005
        rim = lowest + state.get(container, "bb_z")
        pinch, yaw, offset, bottom = self.held(state, cube)
        release_bottom = max(floor + DROP_GAP, rim - RIM_DEPTH)
        release_z = float(pinch[2]) - (bottom - release_bottom)
        target_xy = spot - offset[:2]

        return [*self.release_at(target_xy, release_z, yaw, RELEASE), grip_segment(0.0)]


def _container(objects: dict[str, Object], region: str, target: str) -> Object:
    """The container of goal region ``region``: its target when that is an object (a bin), else
    the object named as the region without ``_goal_region`` (``bowl_red_goal_region``, a table
    square, holds ``bowl_red``)."""
    if target != TABLE:
        return objects[target]
    name = region.removesuffix("_goal_region")
    if name not in objects:
        raise ValueError(
            f"goal region {region!r} lies on the table; expected an object named {name!r} in it"
        )
    return objects[name]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The SortClutteredBlocks3D planning model (the table variants: bins o4/o20, bowls o20)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    if TABLE not in objects:  # the cupboard variant (o12)
        return sort_cupboard3d.create_model(env)
    robot_obj = objects["robot"]
    regions = dict(
        placement_goal(env, "SortClutteredBlocks3D", lambda atom: atom[0] in ("on", "in"))
    )
    specs = env.task.regions  # type: ignore[attr-defined]
    containers = {r: _container(objects, r, specs[r].target) for r in set(regions.values())}
    cubes = tuple(sorted((objects[n] for n in regions), key=lambda o: int(o.name[4:])))
    ctx = SortContext(env, robot_obj, objects[TABLE], regions, containers)
    table_top = float(env.task.fixtures[TABLE].params["height"])  # type: ignore[attr-defined]

    HandEmpty, Holding = hand_predicates()
    Loose = Predicate("Loose", (MOVABLE_TYPE,))
    Sorted = Predicate("Sorted", (MOVABLE_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms, closed, pinch = hand_state(state, robot_obj, HandEmpty)
        on = env.goal_atoms(state)  # type: ignore[attr-defined]
        for c in cubes:
            pos = np.asarray(state[c][:3])
            lifted = pos[2] > table_top + 0.5 * state.get(c, "bb_z") + 0.01
            if closed and lifted and np.linalg.norm(pos - pinch) < HOLD_RADIUS:
                atoms.add(Holding.ground([robot_obj, c]))
            elif on[f"on({c.name}, {regions[c.name]})"]:
                atoms.add(Sorted.ground([c]))
            else:
                atoms.add(Loose.ground([c]))
        return frozenset(atoms)

    o = Variable("?cube", MOVABLE_TYPE)
    pick = pick_operator(o, Loose)
    drop = place_operator(o, Sorted, "Drop")

    return dynamic3d_model(
        "sort_cluttered_blocks3d",
        ctx,
        [HandEmpty, Holding, Loose, Sorted],
        [(pick, PickController), (drop, DropController)],
        {HandEmpty.ground([robot_obj])} | {Sorted.ground([c]) for c in cubes},
        abstraction,
        cubes,
        400,
    )


__all__: Sequence[str] = ["DropController", "PickController", "create_model"]
