"""The Packing3D planning model: move every part from the table into the rack.

Upstream has no planning model for this family. Parts are plates (``Kinematic3DCuboid``) or
triangular prisms (``Kinematic3DTriangle``); typed STRIPS has no common supertype for the two, so
every part predicate and operator comes once per kind, suffixed ``Plate`` or ``Triangle``:

* ``HandEmpty(robot)``; ``HoldingK(robot, part)``.
* ``InRackK(part, rack)``: not held and seated in the rack (the env's own ``part_seated``).
* ``OnTableK(part)``: not held and not seated.

Operators: ``PickK(?robot, ?part)`` (pre HandEmpty, OnTableK; add HoldingK; delete HandEmpty,
OnTableK) and ``PlaceK(?robot, ?part, ?rack)`` (pre HoldingK; add HandEmpty, InRackK; delete
HoldingK). Goal: every part in the rack and HandEmpty. The env's goal also forbids overlapping
parts; the place sampler only proposes poses free of the parts already packed.

Skills (base at its home pose unless a pose is out of reach there, see
:class:`~kinder_gym.models.kinematic3d.tidybot.TableTopController`):

* Pick: a top-down grasp of the part's peg with the finger pads just above the part's top face,
  four yaws (90° apart) in an order the parameter picks.
* Place: the part goes upright into the rack at a sampled pose (position and yaw over the rack's
  inner footprint), 3 mm above the rack floor; open and lift. The sampler packs greedily from the
  rack's −y end: among random yaws (multiples of 15°) and x positions it takes the pose whose
  footprint reaches least far along +y without overlapping the parts already in the rack, so
  later parts keep room (a plate and two triangles fill 0.27 of the rack's 0.28 m). Every
  proposed pose is checked with the env's own seating and overlap tests before moving.

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, Type
from kinder_garden3d.kinematic3d.geometry import quat_yaw, triangle_vertices_2d, yaw_quat
from kinder_garden3d.kinematic3d.object_types import (
    CUBOID_TYPE,
    ROBOT_TYPE,
    TRIANGLE_TYPE,
    WALL_THICKNESS,
)
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

#: The finger pads reach this far below the pinch point; peg grasps keep them above the part.
PEG_PINCH_ABOVE_TOP = 0.03
#: Candidate part yaws of the place sampler.
YAWS = tuple(k * math.pi / 12 for k in range(24))
#: Clearance kept between packed parts' footprints, and from the rack's inner walls.
PACK_MARGIN = 0.002
#: Step of the sampler's scan along +y.
SCAN_STEP = 0.004


def half_depth(f: FloatArray, kind: Type) -> float:
    """Half the thickness of a part (cuboids store half extents, triangles the full depth)."""
    return float(f[11]) if kind == CUBOID_TYPE else float(f[11]) / 2.0


def local_outline(f: FloatArray, kind: Type) -> FloatArray:
    """A part's footprint polygon in its own frame (counter-clockwise)."""
    if kind == CUBOID_TYPE:
        hx, hy = float(f[9]), float(f[10])
        return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return np.asarray(triangle_vertices_2d(float(f[8]), float(f[9]), float(f[10])))


def outline(local: FloatArray, x: float, y: float, yaw: float) -> FloatArray:
    """``local`` turned by ``yaw`` and moved to (x, y)."""
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    out: FloatArray = local @ rot.T + np.array([x, y])
    return out


class PickPartController(TableTopController):
    """Pick a part by its peg. Objects: ``(robot, part)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = "(yaw,): which of the four peg grasp yaws (90° apart) is tried first."

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.robot, "grasp_active") < 0.5

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        part = self.objects[1]
        f = np.asarray(state[part], dtype=np.float64)
        top = float(f[2]) + half_depth(f, part.type)
        pos = np.array([f[0], f[1], top + PEG_PINCH_ABOVE_TOP])
        yaw = quat_yaw(f[3:7])
        yaws = [wrap(yaw + k * math.pi / 2) for k in range(4)]
        start = min(3, int(float(self.params[0]) * 4))
        poses = [(pos, top_down_quat(y)) for y in yaws[start:] + yaws[:start]]
        return self._first_feasible(state, poses, -1.0, salt=1)


class PlaceInRackController(TableTopController):
    """Put the held part into the rack. Objects: ``(robot, part, rack)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(u, v, yaw): the part's centroid goes to fractions (u, v) of the rack's inner footprint, "
        "turned by yaw·2π about z, 3 mm above the rack floor."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "grasp_active") > 0.5

    def _inner(self, state: ObjectCentricState) -> tuple[float, float, float, float, float]:
        """The rack's centre (x, y), inner half extents (x, y) and floor top."""
        r = state[self.objects[2]]
        return (
            float(r[0]),
            float(r[1]),
            float(r[9]) - WALL_THICKNESS,
            float(r[10]) - WALL_THICKNESS,
            float(r[2] - r[11]) + WALL_THICKNESS,
        )

    def _packed(self, state: ObjectCentricState) -> list[FloatArray]:
        """Footprints of the other parts seated in the rack."""
        env = self.context
        out = []
        for p in env.parts:
            if p == self.objects[1] or state[p][7] > 0.5 or not env.part_seated(state, p):
                continue
            f = np.asarray(state[p], dtype=np.float64)
            out.append(outline(local_outline(f, p.type), f[0], f[1], quat_yaw(f[3:7])))
        return out

    def _pose(self, state: ObjectCentricState, params: FloatArray) -> tuple[FloatArray, float]:
        cx, cy, hx, hy, floor = self._inner(state)
        part = self.objects[1]
        f = np.asarray(state[part], dtype=np.float64)
        x = cx - hx + float(params[0]) * 2 * hx
        y = cy - hy + float(params[1]) * 2 * hy
        z = floor + half_depth(f, part.type) + PLACE_GAP
        return np.array([x, y, z]), wrap(float(params[2]) * 2 * math.pi)

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        cx, cy, hx, hy, _ = self._inner(state)
        part = self.objects[1]
        local = local_outline(np.asarray(state[part], dtype=np.float64), part.type)
        packed = self._packed(state)
        best: tuple[float, float, float, float] | None = None  # (reach, x, y, yaw)
        for _ in range(30):
            yaw = float(YAWS[int(rng.integers(len(YAWS)))])
            shape = outline(local, 0.0, 0.0, yaw)
            lo, hi = shape.min(axis=0), shape.max(axis=0)
            x_lo, x_hi = cx - hx - lo[0] + PACK_MARGIN, cx + hx - hi[0] - PACK_MARGIN
            y_lo, y_hi = cy - hy - lo[1] + PACK_MARGIN, cy + hy - hi[1] - PACK_MARGIN
            if x_lo > x_hi or y_lo > y_hi:
                continue
            x = float(rng.uniform(x_lo, x_hi))
            for y in np.arange(y_lo, y_hi + 1e-9, SCAN_STEP):
                if best is not None and y + hi[1] >= best[0]:
                    break
                poly = shape + np.array([x, y])
                if not any(polygons_overlap(poly, q, PACK_MARGIN) for q in packed):
                    best = (float(y + hi[1]), x, float(y), yaw)
                    break
        if best is None:
            return rng.uniform(0.0, 1.0, 3)
        _, x, y, yaw = best
        return np.array(
            [
                (x - cx + hx) / (2 * hx),
                (y - cy + hy) / (2 * hy),
                (yaw % (2 * math.pi)) / (2 * math.pi),
            ]
        )

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        env = self.context
        part = self.objects[1]
        pos, yaw = self._pose(state, self.params)
        # The env's own tests on the part at the pose: seated, and clear of every other part.
        test = state.copy()
        test[part][:3], test[part][3:7], test[part][7] = pos, yaw_quat(yaw), 0.0
        if not env.part_seated(test, part) or any(
            env.parts_overlap(test, part, p) for p in env.parts if p != part
        ):
            raise SkillFailure("PlaceInRackController: the part does not fit there")
        return self._first_feasible(state, self._place_poses(state, pos, [yaw]), 1.0, salt=2)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Packing3D planning model (any number of parts)."""
    robot_obj: Object = env.robot  # type: ignore[attr-defined]
    rack_obj: Object = env.rack  # type: ignore[attr-defined]
    parts: list[Object] = list(env.parts)  # type: ignore[attr-defined]

    HandEmpty = hand_predicates()[0]
    kinds = {CUBOID_TYPE: "Plate", TRIANGLE_TYPE: "Triangle"}
    holding = {t: Predicate(f"Holding{k}", (ROBOT_TYPE, t)) for t, k in kinds.items()}
    on_table = {t: Predicate(f"OnTable{k}", (t,)) for t, k in kinds.items()}
    in_rack = {t: Predicate(f"InRack{k}", (t, CUBOID_TYPE)) for t, k in kinds.items()}

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms = hand_atoms(state, robot_obj, HandEmpty)
        for p in parts:
            if state.get(p, "grasp_active") > 0.5:
                atoms.add(holding[p.type].ground([robot_obj, p]))
            elif env.part_seated(state, p):  # type: ignore[attr-defined]
                atoms.add(in_rack[p.type].ground([p, rack_obj]))
            else:
                atoms.add(on_table[p.type].ground([p]))
        return frozenset(atoms)

    k = Variable("?rack", CUBOID_TYPE)
    skills = []
    for t, name in kinds.items():
        p = Variable("?part", t)
        pick = pick_operator(f"Pick{name}", HandEmpty, holding[t], p, [on_table[t].lift([p])])
        place = place_operator(
            f"Place{name}", HandEmpty, holding[t], p, [in_rack[t].lift([p, k])], params=[k]
        )
        skills += [Skill(pick, PickPartController, env), Skill(place, PlaceInRackController, env)]

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        objs = op.objects
        return objs[1] in parts and (len(objs) == 2 or objs[2] == rack_obj)

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset(
            {HandEmpty.ground([robot_obj])} | {in_rack[p.type].ground([p, rack_obj]) for p in parts}
        )

    return PlanningModel(
        name="packing3d",
        env=env,
        types=(ROBOT_TYPE, CUBOID_TYPE, TRIANGLE_TYPE),
        predicates=(
            HandEmpty,
            *holding.values(),
            *on_table.values(),
            *in_rack.values(),
        ),
        skills=tuple(skills),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=200,
        operator_filter=keep,
    )


__all__: Sequence[str] = [
    "PickPartController",
    "PlaceInRackController",
    "create_model",
    "local_outline",
    "outline",
]
