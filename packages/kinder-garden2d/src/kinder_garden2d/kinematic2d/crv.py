"""The CRV vacuum robot and the kinematic world model shared by the Kinematic2D environments.

A Kinematic2D state is a set of rigid bodies: oriented boxes and circles with a collision layer
(z-order), a static flag and an owner (the object they belong to). :class:`KinematicWorld`
precomputes, for one environment's objects, where each object's geometry lives in the state's
flat array, so turning a state into bodies is a handful of vectorized gathers, and collision
checks are whole-array kernels from :mod:`kinder_garden2d.geometry`.

The robot ("CRV") has four bodies:

* base: a circle of ``base_radius`` (z ALL);
* arm: a box from the base centre to the gripper centre, ``gripper_width / 2`` thick (z SURFACE);
* gripper: a ``gripper_width`` (along the arm) × ``gripper_height`` (across) box centred
  ``arm_joint`` from the base centre (z SURFACE);
* suction zone: a gripper-sized box just beyond the gripper's outer edge, present only while
  ``vacuum > 0.5`` (z NONE: it never collides).

One transition (:meth:`KinematicWorld.transition`): move the robot by the action (theta wrapped,
arm clipped to ``[base_radius, arm_length]``, vacuum set), carry every object that the *previous*
suction zone touched rigidly with the tool tip, optionally push objects that a held object runs
into, then discard the whole proposal if any moving body overlaps an obstacle it may collide with.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from kinder_core import Object, StateLayout
from kinder_garden2d.geometry import (
    BoolArray,
    FloatArray,
    circle_circle_overlap,
    lshape_obbs,
    obb_circle_overlap,
    obb_obb_overlap,
    obbs_from_anchor,
    wrap_angle,
)
from kinder_garden2d.kinematic2d.object_types import (
    CIRCLE,
    DOUBLE_RECTANGLE,
    LOBJECT,
    RECTANGLE,
    ROBOT_FEATURES,
    ZOrder,
)

IntArray = NDArray[np.intp]

ROBOT_OWNER = -1
CONSTANT_OWNER = -2


@dataclass(frozen=True)
class CRVActionLimits:
    """Per-step bounds of the 5-D action ``[dx, dy, dtheta, darm, vacuum]``."""

    max_dx: float = 0.05
    max_dy: float = 0.05
    max_dtheta: float = np.pi / 16
    max_darm: float = 0.1

    def space(self) -> spaces.Box:
        """The action space (float32, as gymnasium learners expect)."""
        low = np.array([-self.max_dx, -self.max_dy, -self.max_dtheta, -self.max_darm, 0.0])
        high = np.array([self.max_dx, self.max_dy, self.max_dtheta, self.max_darm, 1.0])
        return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)


@dataclass(frozen=True)
class RobotGeometry:
    """The robot's bodies for one robot feature vector (see the module docstring)."""

    base: FloatArray  # circle row [cx, cy, r]
    arm: FloatArray  # OBB row
    gripper: FloatArray  # OBB row
    suction: FloatArray  # OBB row
    tool_tip: tuple[float, float]
    vacuum_on: bool


def robot_geometry(robot: Iterable[float]) -> RobotGeometry:
    """The robot's bodies from its nine features (in :data:`ROBOT_FEATURES` order)."""
    x, y, th, br, aj, _, vac, gh, gw = (float(v) for v in robot)
    c, s = float(np.cos(th)), float(np.sin(th))
    return RobotGeometry(
        base=np.array([x, y, br]),
        arm=np.array([x + 0.5 * aj * c, y + 0.5 * aj * s, c, s, 0.5 * aj, 0.25 * gw]),
        gripper=np.array([x + aj * c, y + aj * s, c, s, 0.5 * gw, 0.5 * gh]),
        suction=np.array(
            [x + (aj + 1.5 * gw) * c, y + (aj + 1.5 * gw) * s, c, s, 0.5 * gw, 0.5 * gh]
        ),
        tool_tip=(x + (aj + 0.5 * gw) * c, y + (aj + 0.5 * gw) * s),
        vacuum_on=vac > 0.5,
    )


class Bodies:
    """Boxes and circles with their z-order, static flag and owner (an index into
    :attr:`KinematicWorld.objects`, or :data:`ROBOT_OWNER` / :data:`CONSTANT_OWNER`)."""

    __slots__ = ("circles", "cowner", "cstatic", "cz", "obbs", "rowner", "rstatic", "rz")

    def __init__(
        self,
        obbs: FloatArray,
        rz: FloatArray,
        rstatic: BoolArray,
        rowner: IntArray,
        circles: FloatArray,
        cz: FloatArray,
        cstatic: BoolArray,
        cowner: IntArray,
    ) -> None:
        self.obbs, self.rz, self.rstatic, self.rowner = obbs, rz, rstatic, rowner
        self.circles, self.cz, self.cstatic, self.cowner = circles, cz, cstatic, cowner

    @staticmethod
    def of(
        obbs: ArrayLike = (),
        obb_z: Sequence[float] = (),
        circles: ArrayLike = (),
        circle_z: Sequence[float] = (),
        static: bool = False,
        owner: int = CONSTANT_OWNER,
    ) -> Bodies:
        """Bodies that all share one static flag and owner."""
        o = np.asarray(obbs, dtype=np.float64).reshape(-1, 6)
        c = np.asarray(circles, dtype=np.float64).reshape(-1, 3)
        return Bodies(
            o,
            np.asarray(obb_z, dtype=np.float64).reshape(-1),
            np.full(len(o), static),
            np.full(len(o), owner, dtype=np.intp),
            c,
            np.asarray(circle_z, dtype=np.float64).reshape(-1),
            np.full(len(c), static),
            np.full(len(c), owner, dtype=np.intp),
        )

    @staticmethod
    def concat(parts: Sequence[Bodies]) -> Bodies:
        """All bodies of ``parts``."""
        return Bodies(*(np.concatenate([getattr(p, f) for p in parts]) for f in Bodies._fields()))

    @staticmethod
    def _fields() -> tuple[str, ...]:
        return ("obbs", "rz", "rstatic", "rowner", "circles", "cz", "cstatic", "cowner")

    def select(self, rmask: BoolArray | IntArray, cmask: BoolArray | IntArray) -> Bodies:
        """The boxes picked by ``rmask`` and the circles picked by ``cmask``."""
        return Bodies(
            self.obbs[rmask],
            self.rz[rmask],
            self.rstatic[rmask],
            self.rowner[rmask],
            self.circles[cmask],
            self.cz[cmask],
            self.cstatic[cmask],
            self.cowner[cmask],
        )

    def __len__(self) -> int:
        return len(self.obbs) + len(self.circles)


def _may_collide(za: FloatArray, sa: BoolArray, zb: FloatArray, sb: BoolArray) -> BoolArray:
    """``(n, m)``: may bodies of layers ``za`` and ``zb`` collide (z rules, static pairs never)?"""
    a = za[:, None]
    b = zb[None, :]
    out: BoolArray = (
        ((a == b) | (a == ZOrder.ALL) | (b == ZOrder.ALL))
        & (a != ZOrder.NONE)
        & (b != ZOrder.NONE)
        & ~(sa[:, None] & sb[None, :])
    )
    return out


def collision_matrices(a: Bodies, b: Bodies) -> tuple[BoolArray, BoolArray, BoolArray, BoolArray]:
    """Colliding pairs between ``a`` and ``b`` (z rules applied): box–box, a-box–b-circle,
    a-circle–b-box (as ``(b, a)``), circle–circle."""
    rr = obb_obb_overlap(a.obbs, b.obbs) & _may_collide(a.rz, a.rstatic, b.rz, b.rstatic)
    rc = obb_circle_overlap(a.obbs, b.circles) & _may_collide(a.rz, a.rstatic, b.cz, b.cstatic)
    cr = obb_circle_overlap(b.obbs, a.circles) & _may_collide(b.rz, b.rstatic, a.cz, a.cstatic)
    cc = circle_circle_overlap(a.circles, b.circles) & _may_collide(
        a.cz, a.cstatic, b.cz, b.cstatic
    )
    return rr, rc, cr, cc


def bodies_collide(a: Bodies, b: Bodies) -> bool:
    """Does any body of ``a`` collide with any body of ``b`` (z rules applied)?"""
    if (
        a.obbs.size
        and b.obbs.size
        and np.any(obb_obb_overlap(a.obbs, b.obbs) & _may_collide(a.rz, a.rstatic, b.rz, b.rstatic))
    ):
        return True
    if (
        a.obbs.size
        and b.circles.size
        and np.any(
            obb_circle_overlap(a.obbs, b.circles) & _may_collide(a.rz, a.rstatic, b.cz, b.cstatic)
        )
    ):
        return True
    if (
        a.circles.size
        and b.obbs.size
        and np.any(
            obb_circle_overlap(b.obbs, a.circles) & _may_collide(b.rz, b.rstatic, a.cz, a.cstatic)
        )
    ):
        return True
    return bool(
        a.circles.size
        and b.circles.size
        and np.any(
            circle_circle_overlap(a.circles, b.circles)
            & _may_collide(a.cz, a.cstatic, b.cz, b.cstatic)
        )
    )


def colliding_owner_pairs(bodies: Bodies) -> set[tuple[int, int]]:
    """Pairs of distinct owners with colliding bodies (z rules applied)."""
    rr, rc, cr, cc = collision_matrices(bodies, bodies)
    pairs: set[tuple[int, int]] = set()
    for m, oa, ob in (
        (rr, bodies.rowner, bodies.rowner),
        (rc, bodies.rowner, bodies.cowner),
        (cr, bodies.rowner, bodies.cowner),
        (cc, bodies.cowner, bodies.cowner),
    ):
        for i, j in zip(*np.nonzero(m)):
            p, q = int(oa[i]), int(ob[j])
            if p != q and not (p == CONSTANT_OWNER and q == CONSTANT_OWNER):
                pairs.add((min(p, q), max(p, q)))
    return pairs


def world_walls(xmin: float, xmax: float, ymin: float, ymax: float, thickness: float) -> Bodies:
    """Static z-ALL walls hugging the world box from outside."""
    t = thickness
    w, h = xmax - xmin, ymax - ymin
    anchors = [
        (xmin - t, ymin - t, t, h + 2 * t),  # left
        (xmax, ymin - t, t, h + 2 * t),  # right
        (xmin - t, ymin - t, w + 2 * t, t),  # bottom
        (xmin - t, ymax, w + 2 * t, t),  # top
    ]
    a = np.array(anchors)
    obbs = obbs_from_anchor(a[:, 0], a[:, 1], 0.0, a[:, 2], a[:, 3])
    return Bodies.of(obbs, [ZOrder.ALL] * 4, static=True)


# A family hook: given the proposed state's data and the held objects' indices, move any objects
# the held ones push (in place) and return their indices.
PushFn = Callable[["KinematicWorld", FloatArray, IntArray], IntArray]

_EMPTY = np.zeros(0, dtype=np.intp)


class KinematicWorld:
    """The geometry of one environment's objects, and the CRV transition over it.

    Args:
        layout: The layout of the environment's states (fixes the objects).
        robot: The robot object.
        constants: Static bodies that are not part of the state (walls, tables).
        push: Optional pushing rule (see :data:`PushFn`).
    """

    def __init__(
        self,
        layout: StateLayout,
        robot: Object,
        constants: Bodies,
        push: PushFn | None = None,
    ) -> None:
        self.layout = layout
        self.robot = robot
        self.constants = constants
        self.push = push
        others = [o for o in layout.objects if o != robot]
        rects = [o for o in others if o.type.is_subtype_of(RECTANGLE)]
        lobjs = [o for o in others if o.type.is_subtype_of(LOBJECT)]
        doubles = [o for o in others if o.type.is_subtype_of(DOUBLE_RECTANGLE)]
        circles = [o for o in others if o.type.is_subtype_of(CIRCLE)]
        unknown = set(others) - set(rects + lobjs + doubles + circles)
        if unknown:
            raise ValueError(f"Objects of unsupported types: {sorted(map(repr, unknown))}")
        self.objects: list[Object] = rects + lobjs + doubles + circles
        self.index: dict[Object, int] = {o: i for i, o in enumerate(self.objects)}
        idx = layout.indices
        self.robot_idx = idx([robot], ROBOT_FEATURES)[0]
        self.pose_idx = idx(self.objects, ["x", "y", "theta"])
        self.static_idx = idx(self.objects, ["static"])[:, 0]
        self._rect_idx = idx(rects, ["x", "y", "theta", "width", "height", "z_order", "static"])
        self._l_idx = idx(
            lobjs,
            ["x", "y", "theta", "width", "length_side1", "length_side2", "z_order", "static"],
        )
        self._d_idx = idx(
            doubles,
            [
                *("x", "y", "theta", "width", "height", "z_order", "static"),
                *("x1", "y1", "theta1", "width1", "height1", "z_order1"),
            ],
        )
        self._circ_idx = idx(circles, ["x", "y", "radius", "z_order", "static"])
        n_r, n_l, n_d = len(rects), len(lobjs), len(doubles)
        self._rowner = np.concatenate(
            [
                np.arange(n_r),
                np.repeat(np.arange(n_r, n_r + n_l), 2),
                np.repeat(np.arange(n_r + n_l, n_r + n_l + n_d), 3),
            ]
        ).astype(np.intp)
        self._cowner = np.arange(n_r + n_l + n_d, len(self.objects), dtype=np.intp)
        self._simple = n_l == 0 and n_d == 0
        non_robot = [i for i in range(layout.size) if i not in set(self.robot_idx.tolist())]
        self._object_feature_idx = np.asarray(non_robot, dtype=np.intp)
        self._scene_cache: _Scene | None = None

    # -- bodies ---------------------------------------------------------------------------------
    def object_bodies(self, data: FloatArray) -> Bodies:
        """Bodies of every (non-robot) object of a state."""
        v = data[self._rect_idx]
        obbs = obbs_from_anchor(v[:, 0], v[:, 1], v[:, 2], v[:, 3], v[:, 4])
        rz, rs = v[:, 5], v[:, 6] > 0.5
        if not self._simple:
            parts, zs, ss = [obbs], [rz], [rs]
            for row in data[self._l_idx]:
                x, y, th, w, s1, s2, z, st = row
                parts.append(lshape_obbs(x, y, th, w, s1, s2))
                zs.append(np.array([z, z]))
                ss.append(np.array([st > 0.5] * 2))
            for row in data[self._d_idx]:
                x, y, th, w, h, z, st, x1, y1, th1, w1, h1, z1 = row
                # The inner part splits the outer strip into two bookends (axis-aligned strips).
                a = np.array([[x, y, x1 - x, h], [x1 + w1, y, x + w - x1 - w1, h]])
                parts.append(obbs_from_anchor(a[:, 0], a[:, 1], th, a[:, 2], a[:, 3]))
                parts.append(obbs_from_anchor([x1], [y1], [th1], [w1], [h1]))
                zs.append(np.array([z, z, z1]))
                ss.append(np.array([st > 0.5] * 3))
            obbs, rz, rs = np.concatenate(parts), np.concatenate(zs), np.concatenate(ss)
        c = data[self._circ_idx]
        return Bodies(obbs, rz, rs, self._rowner, c[:, :3], c[:, 3], c[:, 4] > 0.5, self._cowner)

    def robot_bodies(self, data: FloatArray, include_suction: bool = False) -> Bodies:
        """The robot's base, arm and gripper (and suction zone, z NONE, when asked and on)."""
        g = robot_geometry(data[self.robot_idx])
        rects = [g.arm, g.gripper]
        z = [ZOrder.SURFACE, ZOrder.SURFACE]
        if include_suction and g.vacuum_on:
            rects.append(g.suction)
            z.append(ZOrder.NONE)
        return Bodies.of(rects, z, [g.base], [ZOrder.ALL], owner=ROBOT_OWNER)

    def all_bodies(self, data: FloatArray) -> Bodies:
        """Robot, objects and constants."""
        return Bodies.concat([self.robot_bodies(data), self.object_bodies(data), self.constants])

    # -- queries --------------------------------------------------------------------------------
    def colliding_pairs(self, data: FloatArray) -> list[tuple[str, str]]:
        """Names of the pairs of things that collide in a state ("robot", "constant" or object
        names). Empty for every state the transition can produce."""

        def name(i: int) -> str:
            return {ROBOT_OWNER: "robot", CONSTANT_OWNER: "constant"}.get(i) or (
                self.objects[i].name
            )

        return sorted((name(p), name(q)) for p, q in colliding_owner_pairs(self.all_bodies(data)))

    def in_collision(self, data: FloatArray) -> bool:
        """Does any pair of distinct things collide in this state?"""
        return bool(self.colliding_pairs(data))

    def suctioned(self, data: FloatArray) -> IntArray:
        """Indices (into :attr:`objects`) of the non-static objects the suction zone touches
        (empty when the vacuum is off). These move with the gripper on the next step."""
        x, y, th, _, aj, _, vac, gh, gw = data[self.robot_idx].tolist()
        if not vac > 0.5:
            return _EMPTY
        c, s = math.cos(th), math.sin(th)
        d = aj + 1.5 * gw
        suction = np.array([[x + d * c, y + d * s, c, s, 0.5 * gw, 0.5 * gh]])
        sc = self._scene(data)
        cand = np.flatnonzero(_aabb_hits(sc.aabb, _obb_aabb(suction[0])) & sc.movable)
        if not cand.size:
            return _EMPTY
        cr, cc = cand[cand < sc.n_rects], cand[cand >= sc.n_rects] - sc.n_rects
        b = sc.bodies
        hit_r = cr[obb_obb_overlap(suction, b.obbs[cr])[0]]
        hit_c = cc[obb_circle_overlap(suction, b.circles[cc])[0]]
        return np.unique(np.concatenate([b.rowner[hit_r], b.cowner[hit_c]]))

    def held_objects(self, data: FloatArray) -> list[Object]:
        """The objects that are suctioned (held) in this state."""
        return [self.objects[i] for i in self.suctioned(data)]

    # -- dynamics -------------------------------------------------------------------------------
    def transition(self, data: FloatArray, action: FloatArray) -> FloatArray:
        """The next state's data (``data`` itself when the proposal collides)."""
        x, y, th, br, aj, al, _, gh, gw = data[self.robot_idx].tolist()
        dx, dy, dth, darm, vac = action.tolist()
        held = self.suctioned(data)
        new: FloatArray = data.copy()
        nth = (th + dth + math.pi) % (2 * math.pi) - math.pi
        naj = min(max(aj + darm, br), al)
        new[self.robot_idx] = (x + dx, y + dy, nth, br, naj, al, vac, gh, gw)
        moving = held
        if held.size:
            # Rigid motion of the tool-tip frame: rotate about the old tip, then translate to the
            # new tip.
            c0, s0 = math.cos(th), math.sin(th)
            c1, s1 = math.cos(nth), math.sin(nth)
            t0x, t0y = x + (aj + 0.5 * gw) * c0, y + (aj + 0.5 * gw) * s0
            t1x, t1y = x + dx + (naj + 0.5 * gw) * c1, y + dy + (naj + 0.5 * gw) * s1
            rot = nth - th
            cr, sr = math.cos(rot), math.sin(rot)
            pidx = self.pose_idx[held]
            pose = new[pidx]
            rx, ry = pose[:, 0] - t0x, pose[:, 1] - t0y
            pose[:, 0] = t1x + cr * rx - sr * ry
            pose[:, 1] = t1y + sr * rx + cr * ry
            pose[:, 2] = wrap_angle(pose[:, 2] + rot)
            new[pidx] = pose
            if self.push is not None:
                pushed = self.push(self, new, held)
                if pushed.size:
                    moving = np.union1d(held, pushed)
        if self._moving_collides(data, new, moving):
            return data
        return new

    def _scene(self, data: FloatArray) -> _Scene:
        """Bodies of the objects and constants of ``data`` (cached on the objects' features)."""
        key = data[self._object_feature_idx].tobytes()
        if self._scene_cache is None or self._scene_cache.key != key:
            b = Bodies.concat([self.object_bodies(data), self.constants])
            aabb = np.concatenate([_obbs_aabb(b.obbs), _circles_aabb(b.circles)])
            z = np.concatenate([b.rz, b.cz])
            static = np.concatenate([b.rstatic, b.cstatic])
            owner = np.concatenate([b.rowner, b.cowner])
            self._scene_cache = _Scene(
                key, b, aabb, z, z != ZOrder.NONE, (owner >= 0) & ~static, owner, len(b.obbs)
            )
        return self._scene_cache

    def _moving_collides(self, old: FloatArray, new: FloatArray, moving: IntArray) -> bool:
        """Does the robot of ``new`` (or a ``moving`` object) collide with anything else?

        The non-moving objects are the same in ``old`` and ``new``, so the cached bodies of
        ``old`` serve as obstacles. An AABB broad phase skips the exact tests when nothing is
        near.
        """
        sc = self._scene(old)
        x, y, _, br, aj, _, _, gh, gw = new[self.robot_idx].tolist()
        reach = max(br, math.hypot(aj + 0.5 * gw, 0.5 * gh))
        box = [x - reach, x + reach, y - reach, y + reach]
        obstacle = sc.collidable
        mover: Bodies | None = None
        if moving.size:
            nb = self.object_bodies(new)
            mover = nb.select(np.isin(nb.rowner, moving), np.isin(nb.cowner, moving))
            lo = np.concatenate([_obbs_aabb(mover.obbs), _circles_aabb(mover.circles)])
            box = [
                min(box[0], lo[:, 0].min()),
                max(box[1], lo[:, 1].max()),
                min(box[2], lo[:, 2].min()),
                max(box[3], lo[:, 3].max()),
            ]
            obstacle = obstacle & ~np.isin(sc.owner, moving)
        cand = np.flatnonzero(_aabb_hits(sc.aabb, box) & obstacle)
        if not cand.size:
            return False
        robot = self.robot_bodies(new)
        mover = robot if mover is None else Bodies.concat([robot, mover])
        n = sc.n_rects
        return bodies_collide(mover, sc.bodies.select(cand[cand < n], cand[cand >= n] - n))


@dataclass
class _Scene:
    key: bytes
    bodies: Bodies  # objects, then constants
    aabb: FloatArray  # (boxes + circles, 4): xmin, xmax, ymin, ymax
    z: FloatArray
    collidable: BoolArray  # z-order is not NONE
    movable: BoolArray  # a non-static object
    owner: IntArray
    n_rects: int


def _obb_aabb(b: FloatArray) -> list[float]:
    cx, cy, c, s, hw, hh = b.tolist()
    ex, ey = abs(c) * hw + abs(s) * hh, abs(s) * hw + abs(c) * hh
    return [cx - ex, cx + ex, cy - ey, cy + ey]


def _obbs_aabb(b: FloatArray) -> FloatArray:
    ac, as_ = np.abs(b[:, 2]), np.abs(b[:, 3])
    ex = ac * b[:, 4] + as_ * b[:, 5]
    ey = as_ * b[:, 4] + ac * b[:, 5]
    out: FloatArray = np.stack([b[:, 0] - ex, b[:, 0] + ex, b[:, 1] - ey, b[:, 1] + ey], axis=1)
    return out


def _circles_aabb(c: FloatArray) -> FloatArray:
    r = c[:, 2]
    out: FloatArray = np.stack([c[:, 0] - r, c[:, 0] + r, c[:, 1] - r, c[:, 1] + r], axis=1)
    return out


def _aabb_hits(aabbs: FloatArray, box: Sequence[float]) -> BoolArray:
    out: BoolArray = (
        (aabbs[:, 0] <= box[1])
        & (aabbs[:, 1] >= box[0])
        & (aabbs[:, 2] <= box[3])
        & (aabbs[:, 3] >= box[2])
    )
    return out
