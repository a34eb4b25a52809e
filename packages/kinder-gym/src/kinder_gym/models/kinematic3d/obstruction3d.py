"""The Obstruction3D planning model: clear the target region, then put the block on it.

Upstream has no planning model for this family; this one follows the 2D Obstruction models. The
base mostly stays at its home pose beside the table, from which the arm reaches nearly the whole
table top; for poses too close to the arm it backs off 0.15 m (arm retracted first).

Concepts (over the block, the obstructions and the region; held objects are in none of the
placement predicates):

* ``HandEmpty(robot)`` / ``Holding(robot, object)``.
* ``Obstructing(object, region)``: a not-held obstruction whose footprint overlaps the region's.
* ``OnTable(object)``: a not-held obstruction off the region, or the block resting elsewhere than
  on the region.
* ``OnRegion(block, region)``: the env's own goal test (not held, resting on the region).
* ``ObstructedK(region)`` for K = 0 … N (N obstructions): exactly K obstructions obstruct the
  region. STRIPS has no "for all", so the count is how an operator can ask for a clear region;
  the K-th pick moves the count from K to K − 1.

Operators: ``PickObstructionK(?robot, ?obstruction, ?region)`` (pre HandEmpty,
Obstructing, ObstructedK; add Holding, ObstructedK−1; delete HandEmpty, Obstructing,
ObstructedK), ``PlaceOnTable(?robot, ?obstruction)`` (pre Holding; add HandEmpty, OnTable),
``PickBlock(?robot, ?block)`` (pre HandEmpty, OnTable; add Holding) and
``PlaceOnRegion(?robot, ?block, ?region)`` (pre Holding, Obstructed0; add HandEmpty, OnRegion).
Goal: ``OnRegion(block, region)`` and ``HandEmpty``.

Skills (collision-checked with the env's own pybullet geometry through
:class:`~kinder_gym.models.kinematic3d.tidybot.ConfigChecker`; arm paths by OMPL RRT-Connect;
IK by the robot model's mink solver). Each tries the current base pose, then the home pose, then
the home pose backed off, and the first end-effector pose that has IK solutions and a
collision-free approach:

* Pick: a top-down grasp at the object's centre, grasp yaws every 22.5° (those the gripper can
  close across) in an order the parameter picks. A yaw is kept only if the open pads, and the
  pads closed on the object, clear every other object's footprint; the pinch point is raised so
  the pads pass over the support and any shorter neighbour under them while still covering
  5 mm of the object (tightly packed obstructions: the tall one is picked first, from above its
  neighbours). Move the arm above the grasp, descend, close, lift.
* PlaceOnTable: the held obstruction goes upright to a sampled free spot of the table (off the
  region, clear of the block and the other obstructions), 3 mm above the top; open and lift.
* PlaceOnRegion: the block goes onto the region's centre, aligned with it (two yaws), 3 mm above
  it; open and lift.

:class:`TableTopController` (fixed-base reach) is shared with the Packing3D model. Imports
kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.geometry import quat_yaw
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE, ROBOT_TYPE
from kinder_garden3d.kinematic3d.obstruction3d import block_on_region
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import pick_operator, place_operator
from kinder_gym.models.kinematic3d.tidybot import (
    PLACE_GAP,
    ConfigWaypoint,
    TableTopController,
    hand_atoms,
    hand_predicates,
    polygons_overlap,
    top_down_quat,
    wrap,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import Skill, SkillFailure

#: The finger pads reach this far below the pinch point; grasps keep them this far above the
#: surface under the object (plus a margin).
PAD_BELOW_PINCH = 0.025
#: Half width of the open gripper across its closing direction (pads included).
OPEN_HALF_WIDTH = 0.052
#: The open finger pads: centre distance from the pinch point along the closing direction, and
#: half extents (along it, across it).
PAD_CENTRE = 0.047
PAD_HALF = (0.0045, 0.011)
#: Widest object side the open gripper closes across (its stroke is 85 mm).
MAX_GRASP_WIDTH = 0.08


def footprint(f: FloatArray) -> tuple[tuple[float, float], tuple[float, float]]:
    """Centre and half extents of the axis-aligned box around a cuboid's (yawed) footprint."""
    yaw = quat_yaw(np.asarray(f[3:7]))
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    hx = c * float(f[9]) + s * float(f[10])
    hy = s * float(f[9]) + c * float(f[10])
    return (float(f[0]), float(f[1])), (hx, hy)


def overlap(
    a: tuple[tuple[float, float], tuple[float, float]],
    b: tuple[tuple[float, float], tuple[float, float]],
    margin: float = 0.0,
) -> bool:
    """Whether two (centre, half extents) rectangles overlap, each grown by ``margin``."""
    (ax, ay), (ahx, ahy) = a
    (bx, by), (bhx, bhy) = b
    return abs(ax - bx) < ahx + bhx + margin and abs(ay - by) < ahy + bhy + margin


def box_outline(f: FloatArray) -> FloatArray:
    """The (yawed) footprint polygon of a cuboid."""
    yaw = quat_yaw(np.asarray(f[3:7]))
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = float(f[9]), float(f[10])
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    out: FloatArray = local @ np.array([[c, s], [-s, c]]) + np.array([f[0], f[1]])
    return out


def pad_outlines(x: float, y: float, ee_yaw: float, centre: float = PAD_CENTRE) -> list[FloatArray]:
    """Footprints of the two finger pads of a top-down grasp at (x, y), their centres
    ``centre`` from it (open by default)."""
    d = ee_yaw + math.pi / 2  # the closing direction
    u = np.array([math.cos(d), math.sin(d)])
    v = np.array([-u[1], u[0]])
    out = []
    for side in (-1.0, 1.0):
        c = np.array([x, y]) + side * centre * u
        out.append(
            np.array(
                [
                    c + su * PAD_HALF[0] * u + sv * PAD_HALF[1] * v
                    for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))
                ]
            )
        )
    return out


Obstacle = tuple[FloatArray, float, float]
"""A footprint polygon and its z range."""


def grasp_poses(
    f: FloatArray, obstacles: Sequence[Obstacle], pref: float
) -> list[tuple[FloatArray, FloatArray]]:
    """Top-down grasps of an upright cuboid whose open pads clear ``obstacles``.

    Grasp yaws every 22.5° (those whose closing width fits the gripper), the one ``pref`` picks
    first; the pinch point sits at the centre, raised so the pads clear what lies under them (the
    support, or shorter neighbours), as long as the pads still cover 5 mm of the object.
    """
    yaw = quat_yaw(np.asarray(f[3:7]))
    hx, hy = float(f[9]), float(f[10])
    top, bottom = float(f[2] + f[11]), float(f[2] - f[11])
    n = 16
    start = min(n - 1, int(pref * n))
    poses = []
    for k in [*range(start, n), *range(start)]:
        ee_yaw = wrap(yaw + k * math.pi / 8)
        rel = math.pi / 2 + k * math.pi / 8  # the closing direction in the object's frame
        width = 2 * (hx * abs(math.cos(rel)) + hy * abs(math.sin(rel)))
        if width > MAX_GRASP_WIDTH:
            continue
        # The pads open, and closed on the object (the env rejects a grasp whose closed pads
        # touch anything else).
        x, y = float(f[0]), float(f[1])
        pads = pad_outlines(x, y, ee_yaw) + pad_outlines(x, y, ee_yaw, width / 2 + PAD_HALF[0])
        # The pads' lowest point must clear every obstacle under them.
        floor = bottom
        for poly, z0, z1 in obstacles:
            if z0 < top and any(polygons_overlap(p, poly, 0.002) for p in pads):
                floor = max(floor, z1)
        z = max(float(f[2]), floor + PAD_BELOW_PINCH + 0.003)
        if z - PAD_BELOW_PINCH > top - 0.005:
            continue
        poses.append((np.array([float(f[0]), float(f[1]), z]), top_down_quat(ee_yaw)))
    return poses


class PickController(TableTopController):
    """Pick a cuboid off the table or the region. Objects: ``(robot, object, ...)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = "(yaw,): which of the top-down grasp yaws (22.5° apart) is tried first."

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.robot, "grasp_active") < 0.5

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        env = self.context
        obj = self.objects[1]
        f = np.asarray(state[obj], dtype=np.float64)
        obstacles = []
        for other in [env.region, env.block, *env.obstructions]:
            if other != obj:
                g = np.asarray(state[other], dtype=np.float64)
                obstacles.append((box_outline(g), float(g[2] - g[11]), float(g[2] + g[11])))
        poses = grasp_poses(f, obstacles, float(self.params[0]))
        if not poses:
            raise SkillFailure(f"PickController: no clear grasp of {obj.name}")
        return self._first_feasible(state, poses, -1.0, salt=1)


class PlaceOnTableController(TableTopController):
    """Put the held obstruction on a free spot of the table. Objects: ``(robot, object)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(u, v, yaw): the object's centre goes to fractions (u, v) of the table top (shrunk by "
        "the object's footprint), 3 mm above it; yaw picks which of four object yaws (90° apart, "
        "kept relative to the grasp) is tried first."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "grasp_active") > 0.5

    def _spot(self, state: ObjectCentricState, u: float, v: float) -> FloatArray:
        env = self.context
        cfg = env.config
        obj = self.objects[1]
        f = state[obj]
        r = float(np.hypot(f[9], f[10])) + 0.005
        tx, ty, tz = cfg.table_pos
        hx, hy, hz = cfg.table_half
        x = tx - hx + r + u * max(0.0, 2 * (hx - r))
        y = ty - hy + r + v * max(0.0, 2 * (hy - r))
        return np.array([x, y, tz + hz + float(f[11]) + PLACE_GAP])

    def free(self, state: ObjectCentricState, spot: FloatArray) -> bool:
        """Whether the object fits at ``spot`` away from the region, the block and the rest."""
        env = self.context
        f = state[self.objects[1]]
        r = float(np.hypot(f[9], f[10]))
        mine = ((float(spot[0]), float(spot[1])), (r, r))
        for other in [env.region, env.block, *env.obstructions]:
            if other == self.objects[1]:
                continue
            # The block still has to be grasped: leave room for the open fingers around it.
            margin = OPEN_HALF_WIDTH if other == env.block else 0.02
            if overlap(mine, footprint(np.asarray(state[other])), margin):
                return False
        return True

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        params = rng.uniform(0.0, 1.0, 3)
        for _ in range(100):
            if self.free(state, self._spot(state, float(params[0]), float(params[1]))):
                break
            params[:2] = rng.uniform(0.0, 1.0, 2)
        return params

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        u, v, pref = (float(p) for p in self.params)
        spot = self._spot(state, u, v)
        if not self.free(state, spot):
            raise SkillFailure("PlaceOnTableController: the spot is taken")
        # Object yaws that keep the end effector's yaw near its usual one first.
        tf_yaw = quat_yaw(np.asarray(state[self.robot][15:19]))
        # A top-down grasp flips the object's frame about y: with the grasp's yaw t, the
        # object's yaw is the end effector's plus π − t.
        base = wrap(math.pi - tf_yaw)
        yaws = [wrap(base + k * math.pi / 2) for k in range(4)]
        start = min(3, int(pref * 4))
        poses = self._place_poses(state, spot, yaws[start:] + yaws[:start])
        return self._first_feasible(state, poses, 1.0, salt=2)


class PlaceOnRegionController(TableTopController):
    """Put the held block on the region. Objects: ``(robot, block, region)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = "(yaw,): which of the two block yaws aligned with the region is tried first."

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "grasp_active") > 0.5

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        _, block, region = self.objects
        r = np.asarray(state[region], dtype=np.float64)
        b = np.asarray(state[block], dtype=np.float64)
        spot = np.array([r[0], r[1], r[2] + r[11] + b[11] + PLACE_GAP])
        ryaw = quat_yaw(r[3:7])
        yaws = [ryaw, wrap(ryaw + math.pi)]
        if self.params[0] >= 0.5:
            yaws.reverse()
        return self._first_feasible(state, self._place_poses(state, spot, yaws), 1.0, salt=3)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Obstruction3D planning model (any number of obstructions)."""
    robot_obj: Object = env.robot  # type: ignore[attr-defined]
    region_obj: Object = env.region  # type: ignore[attr-defined]
    block_obj: Object = env.block  # type: ignore[attr-defined]
    obstructions: list[Object] = list(env.obstructions)  # type: ignore[attr-defined]
    tol = float(env.config.min_placement_dist)  # type: ignore[attr-defined]
    n = len(obstructions)

    HandEmpty, Holding = hand_predicates()
    Obstructing = Predicate("Obstructing", (CUBOID_TYPE, CUBOID_TYPE))
    OnTable = Predicate("OnTable", (CUBOID_TYPE,))
    OnRegion = Predicate("OnRegion", (CUBOID_TYPE, CUBOID_TYPE))
    Obstructed = [Predicate(f"Obstructed{k}", (CUBOID_TYPE,)) for k in range(n + 1)]

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms = hand_atoms(state, robot_obj, HandEmpty)
        region = np.asarray(state[region_obj])
        region_fp = footprint(region)
        count = 0
        for o in obstructions:
            if state.get(o, "grasp_active") > 0.5:
                atoms.add(Holding.ground([robot_obj, o]))
            elif overlap(footprint(np.asarray(state[o])), region_fp):
                atoms.add(Obstructing.ground([o, region_obj]))
                count += 1
            else:
                atoms.add(OnTable.ground([o]))
        atoms.add(Obstructed[count].ground([region_obj]))
        if state.get(block_obj, "grasp_active") > 0.5:
            atoms.add(Holding.ground([robot_obj, block_obj]))
        elif block_on_region(np.asarray(state[block_obj]), region, tol):
            atoms.add(OnRegion.ground([block_obj, region_obj]))
        else:
            atoms.add(OnTable.ground([block_obj]))
        return frozenset(atoms)

    o = Variable("?obstruction", CUBOID_TYPE)
    b = Variable("?block", CUBOID_TYPE)
    g = Variable("?region", CUBOID_TYPE)
    picks = [
        pick_operator(
            f"PickObstruction{k}",
            HandEmpty,
            Holding,
            o,
            [Obstructing.lift([o, g]), Obstructed[k].lift([g])],
            also_add=[Obstructed[k - 1].lift([g])],
            params=[g],
        )
        for k in range(1, n + 1)
    ]
    place_table = place_operator("PlaceOnTable", HandEmpty, Holding, o, [OnTable.lift([o])])
    pick_block = pick_operator("PickBlock", HandEmpty, Holding, b, [OnTable.lift([b])])
    place_region = place_operator(
        "PlaceOnRegion",
        HandEmpty,
        Holding,
        b,
        [OnRegion.lift([b, g])],
        also_need=[Obstructed[0].lift([g])],
        params=[g],
    )

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        objs = op.objects
        if op.parent is pick_block or op.parent is place_region:
            return objs[1] == block_obj and (len(objs) == 2 or objs[2] == region_obj)
        if objs[1] not in obstructions:
            return False
        return len(objs) == 2 or objs[2] == region_obj

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({HandEmpty.ground([robot_obj]), OnRegion.ground([block_obj, region_obj])})

    skills = [Skill(op, PickController, env) for op in picks]
    skills += [
        Skill(place_table, PlaceOnTableController, env),
        Skill(pick_block, PickController, env),
        Skill(place_region, PlaceOnRegionController, env),
    ]
    return PlanningModel(
        name="obstruction3d",
        env=env,
        types=(ROBOT_TYPE, CUBOID_TYPE),
        predicates=(HandEmpty, Holding, Obstructing, OnTable, OnRegion, *Obstructed),
        skills=tuple(skills),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=200,
        operator_filter=keep,
    )


__all__: Sequence[str] = [
    "PickController",
    "PlaceOnRegionController",
    "PlaceOnTableController",
    "TableTopController",
    "box_outline",
    "create_model",
    "footprint",
    "grasp_poses",
    "overlap",
    "pad_outlines",
]
