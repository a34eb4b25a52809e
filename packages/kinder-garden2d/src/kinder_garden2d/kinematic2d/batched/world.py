"""The CRV transition over a batch of Kinematic2D states, in whole-array numpy.

:class:`BatchedWorld` holds N states of one Kinematic2D env as an ``(N, D)`` array in that env's
state layout and computes :meth:`KinematicWorld.transition
<kinder_garden2d.kinematic2d.crv.KinematicWorld.transition>` for all of them at once: move the
robot, carry the objects the previous suction zone touched, let the family push objects, and
keep the old state of every env whose proposal collides. The single env's broad phase (axis
aligned boxes around the moving bodies) is reproduced too, so every decision, and every number,
equals the single env's.

Static objects (static flag set) and the env's constant bodies (walls, tables) never move, so
their bodies are built once per episode (by the single env's own ``object_bodies``) when a
sub-env resets. Movable objects' bodies are rebuilt every step from the state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinder_garden2d.geometry import BoolArray, FloatArray
from kinder_garden2d.kinematic2d.base import Kinematic2DEnv
from kinder_garden2d.kinematic2d.batched.kernels import (
    aabb_hits,
    anchored_obbs,
    circle_circle_pairs,
    circles_aabb,
    lshape_pairs,
    obb_circle_pairs,
    obb_obb_pairs,
    obbs_aabb,
    py_hypot,
)
from kinder_garden2d.kinematic2d.crv import CONSTANT_OWNER, Bodies, IntArray
from kinder_garden2d.kinematic2d.object_types import (
    CIRCLE,
    DOUBLE_RECTANGLE,
    LOBJECT,
    RECTANGLE,
    ZOrder,
)

_NONE = float(ZOrder.NONE)
_ALL = float(ZOrder.ALL)
_SURFACE = float(ZOrder.SURFACE)


def may_collide(za: FloatArray, zb: FloatArray) -> BoolArray:
    """``(A, B)``: may layers ``za`` and ``zb`` collide? (The single env's z rule; the static
    rule never applies here because every moving body is non-static.)"""
    a, b = za[:, None], zb[None, :]
    out: BoolArray = ((a == b) | (a == _ALL) | (b == _ALL)) & (a != _NONE) & (b != _NONE)
    return out


class BatchedWorld:
    """The transition of one Kinematic2D env's states, N at a time.

    Args:
        env: A single env of the family (its world, exemplar state and sampler are used).

    Raises:
        ValueError: when the env has a movable object whose shape has no batched body builder
            (double rectangles; every shipped family keeps them static).
    """

    def __init__(self, env: Kinematic2DEnv) -> None:
        self.env = env
        world = env.world
        layout = world.layout
        exemplar = env.exemplar_state().data
        self.size = layout.size
        self.robot_idx: IntArray = world.robot_idx
        idx = layout.indices
        objects = world.objects
        static = exemplar[world.static_idx] > 0.5
        movable = [o for o, st in zip(objects, static) if not st]
        doubles = [o.name for o in movable if o.type.is_subtype_of(DOUBLE_RECTANGLE)]
        if doubles:
            raise ValueError(
                f"{type(env).__name__}: movable double rectangles {doubles} are not supported by "
                f"the batched world; expected them static"
            )
        if world.push is not None and type(self).push is BatchedWorld.push:
            raise ValueError(
                f"{type(env).__name__} pushes objects; its batched world must override push()"
            )
        rects = [o for o in movable if o.type.is_subtype_of(RECTANGLE)]
        lobjs = [o for o in movable if o.type.is_subtype_of(LOBJECT)]
        circles = [o for o in movable if o.type.is_subtype_of(CIRCLE)]
        self.movable = [*rects, *lobjs, *circles]
        self.num_movable = len(self.movable)
        self._rect_idx = idx(rects, ["x", "y", "theta", "width", "height"])
        self._l_idx = idx(lobjs, ["x", "y", "theta", "width", "length_side1", "length_side2"])
        self._circ_idx = idx(circles, ["x", "y", "radius"])
        self._pose_idx = idx(self.movable, ["x", "y", "theta"])
        n_r, n_l = len(rects), len(lobjs)
        # Owner (index into self.movable) of each movable box and circle.
        self._obb_owner = np.concatenate(
            [np.arange(n_r), np.repeat(np.arange(n_r, n_r + n_l), 2)]
        ).astype(np.intp)
        self._circ_owner = np.arange(n_r + n_l, self.num_movable, dtype=np.intp)
        z_of = {o: float(exemplar[layout.index(o, "z_order")]) for o in self.movable}
        self._mz_obb = np.array([z_of[self.movable[i]] for i in self._obb_owner], dtype=float)
        self._mz_circ = np.array([z_of[self.movable[i]] for i in self._circ_owner], dtype=float)
        # Features that fix which bodies exist and how they collide: checked on every reset.
        zfeat = [(o, f) for o in objects for f in o.type.features if f in ("static", "z_order")]
        zfeat += [(o, "z_order1") for o in objects if o.type.is_subtype_of(DOUBLE_RECTANGLE)]
        self._fixed_idx = np.array([layout.index(o, f) for o, f in zfeat], dtype=np.intp)
        self._fixed_values = exemplar[self._fixed_idx]
        self._fixed_names = [f"{o.name}.{f}" for o, f in zfeat]
        # Static obstacles: the static objects' and constants' bodies that may collide.
        static_owner = {world.index[o] for o, st in zip(objects, static) if st}
        scene = self._scene(exemplar)
        self._sel_obb = np.array(
            [(o in static_owner or o == CONSTANT_OWNER) for o in scene.rowner.tolist()], dtype=bool
        ) & (scene.rz != _NONE)
        self._sel_circ = np.array(
            [(o in static_owner or o == CONSTANT_OWNER) for o in scene.cowner.tolist()], dtype=bool
        ) & (scene.cz != _NONE)
        self._sz_obb = scene.rz[self._sel_obb]
        self._sz_circ = scene.cz[self._sel_circ]
        # Obstacles of a step: the static bodies, then the movable objects' bodies.
        oz_obb = np.concatenate([self._sz_obb, self._mz_obb])
        oz_circ = np.concatenate([self._sz_circ, self._mz_circ])
        robot_z_obb = np.array([_SURFACE, _SURFACE])  # arm, gripper
        robot_z_circ = np.array([_ALL])  # base
        # Which (mover body, obstacle body) pairs may collide, by layer: the robot's bodies and
        # the movable objects' bodies against every obstacle body.
        self._may_robot = _MayTable(
            may_collide(robot_z_obb, oz_obb),
            may_collide(robot_z_obb, oz_circ),
            may_collide(robot_z_circ, oz_obb),
            may_collide(robot_z_circ, oz_circ),
        )
        self._may_movable = _MayTable(
            may_collide(self._mz_obb, oz_obb),
            may_collide(self._mz_obb, oz_circ),
            may_collide(self._mz_circ, oz_obb),
            may_collide(self._mz_circ, oz_circ),
        )
        self._m_collidable_obb = self._mz_obb != _NONE
        self._m_collidable_circ = self._mz_circ != _NONE
        self.static_obbs = np.zeros((0, len(self._sz_obb), 6))
        self.static_circles = np.zeros((0, len(self._sz_circ), 3))
        self.static_obb_aabb = np.zeros((0, len(self._sz_obb), 4))
        self.static_circ_aabb = np.zeros((0, len(self._sz_circ), 4))

    # -- per-episode scenery --------------------------------------------------------------------
    def _scene(self, data: FloatArray) -> Bodies:
        world = self.env.world
        return Bodies.concat([world.object_bodies(data), world.constants])

    def allocate(self, num_envs: int) -> None:
        """Make room for ``num_envs`` sub-envs' static bodies (filled by :meth:`load_statics`)."""
        self.static_obbs = np.zeros((num_envs, len(self._sz_obb), 6))
        self.static_circles = np.zeros((num_envs, len(self._sz_circ), 3))
        self.static_obb_aabb = np.zeros((num_envs, len(self._sz_obb), 4))
        self.static_circ_aabb = np.zeros((num_envs, len(self._sz_circ), 4))

    def check_fixed(self, data: FloatArray, row: int) -> None:
        """Raise unless a state keeps the static flags and layers this world was built for."""
        bad = np.flatnonzero(data[self._fixed_idx] != self._fixed_values)
        if bad.size:
            names = [self._fixed_names[i] for i in bad]
            raise ValueError(
                f"{type(self.env).__name__}: sub-env {row}'s state changes {names} from the "
                f"values every state of this env has ({self._fixed_values[bad].tolist()}); the "
                f"batched world needs them fixed"
            )

    def load_statics(self, rows: IntArray, data: FloatArray) -> None:
        """Build the static bodies of sub-envs ``rows`` from their states ``data[rows]``."""
        for row in rows.tolist():
            self.check_fixed(data[row], row)
            scene = self._scene(data[row])
            self.static_obbs[row] = scene.obbs[self._sel_obb]
            self.static_circles[row] = scene.circles[self._sel_circ]
        self.static_obb_aabb[rows] = obbs_aabb(self.static_obbs[rows])
        self.static_circ_aabb[rows] = circles_aabb(self.static_circles[rows])

    # -- bodies ---------------------------------------------------------------------------------
    def movable_bodies(self, data: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(N, Bm, 6)`` boxes and ``(N, Cm, 3)`` circles of the movable objects."""
        n = len(data)
        if not self.num_movable:
            return np.zeros((n, 0, 6)), np.zeros((n, 0, 3))
        r = data[:, self._rect_idx]
        parts = [anchored_obbs(r[..., 0], r[..., 1], r[..., 2], r[..., 3], r[..., 4])]
        if self._l_idx.size:
            v = data[:, self._l_idx]
            pairs = lshape_pairs(v[..., 0], v[..., 1], v[..., 2], v[..., 3], v[..., 4], v[..., 5])
            parts.append(pairs.reshape(n, -1, 6))
        obbs = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)
        return obbs, data[:, self._circ_idx]

    @staticmethod
    def robot_bodies(robot: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(N, 2, 6)`` arm and gripper boxes and the ``(N, 1, 3)`` base circle of robots
        ``(N, 9)`` (``robot_geometry`` elementwise)."""
        x, y, th, br, aj, _, _, gh, gw = robot.T
        c, s = np.cos(th), np.sin(th)
        arm = np.stack([x + 0.5 * aj * c, y + 0.5 * aj * s, c, s, 0.5 * aj, 0.25 * gw], -1)
        grip = np.stack([x + aj * c, y + aj * s, c, s, 0.5 * gw, 0.5 * gh], -1)
        return np.stack([arm, grip], 1), np.stack([x, y, br], -1)[:, None, :]

    # -- dynamics -------------------------------------------------------------------------------
    def suctioned(self, data: FloatArray, mov_obbs: FloatArray, mov_circ: FloatArray) -> BoolArray:
        """``(N, M)``: which movable objects each suction zone touches (``suctioned``)."""
        n = len(data)
        held = np.zeros((n, self.num_movable), dtype=bool)
        if not self.num_movable:
            return held
        robot = data[:, self.robot_idx]
        rows = np.flatnonzero(robot[:, 6] > 0.5)
        if not rows.size:
            return held
        x, y, th, _, aj, _, _, gh, gw = robot[rows].T
        c, s = np.cos(th), np.sin(th)
        d = aj + 1.5 * gw
        hw, hh = 0.5 * gw, 0.5 * gh
        cx, cy = x + d * c, y + d * s
        suction = np.stack([cx, cy, c, s, hw, hh], -1)
        ex, ey = np.abs(c) * hw + np.abs(s) * hh, np.abs(s) * hw + np.abs(c) * hh
        box = np.stack([cx - ex, cx + ex, cy - ey, cy + ey], -1)
        if self._obb_owner.size:
            o = mov_obbs[rows]
            r, j = np.nonzero(aabb_hits(obbs_aabb(o), box))
            ok = obb_obb_pairs(suction[r], o[r, j])
            held[rows[r[ok]], self._obb_owner[j[ok]]] = True
        if self._circ_owner.size:
            ci = mov_circ[rows]
            r, j = np.nonzero(aabb_hits(circles_aabb(ci), box))
            ok = obb_circle_pairs(suction[r], ci[r, j])
            held[rows[r[ok]], self._circ_owner[j[ok]]] = True
        return held

    def push(self, new: FloatArray, held: BoolArray) -> BoolArray:
        """The family's pushing rule: move (in ``new``, in place) the objects that held objects
        run into and return which were pushed (``(N, M)``). No pushing by default."""
        return np.zeros_like(held)

    def transition(self, data: FloatArray, action: FloatArray) -> FloatArray:
        """The next states ``(N, D)`` of states ``data`` under clipped actions ``(N, 5)``."""
        robot = data[:, self.robot_idx]
        x, y, th, br, aj, al, _, gh, gw = np.ascontiguousarray(robot.T)
        dx, dy, dth, darm, vac = np.ascontiguousarray(action.T)
        mov_obbs, mov_circ = self.movable_bodies(data)
        held = self.suctioned(data, mov_obbs, mov_circ)
        new: FloatArray = data.copy()
        nth = np.mod(th + dth + np.pi, 2 * np.pi) - np.pi
        naj = np.minimum(np.maximum(aj + darm, br), al)
        nx, ny = x + dx, y + dy
        ix, iy, ith, _, iaj, _, ivac, _, _ = self.robot_idx
        for i, v in ((ix, nx), (iy, ny), (ith, nth), (iaj, naj), (ivac, vac)):
            new[:, i] = v
        moving = held
        rows = np.flatnonzero(held.any(axis=1))
        if rows.size:
            self._carry(
                new, rows, held[rows], robot[rows], nth[rows], naj[rows], dx[rows], dy[rows]
            )
            pushed = self.push(new, held)
            moving = held | pushed
            rows = np.flatnonzero(moving.any(axis=1))
        moved_robot = np.stack([nx, ny, nth, br, naj, al, vac, gh, gw])
        collide = self._collides(new, moved_robot, moving, rows, mov_obbs, mov_circ)
        new[collide] = data[collide]
        return new

    def _carry(
        self,
        new: FloatArray,
        rows: IntArray,
        held: BoolArray,
        robot: FloatArray,
        nth: FloatArray,
        naj: FloatArray,
        dx: FloatArray,
        dy: FloatArray,
    ) -> None:
        """Move the held objects of sub-envs ``rows`` rigidly with the tool tip."""
        x, y, th, _, aj, _, _, _, gw = (v[:, None] for v in robot.T)
        nth, naj, dx, dy = nth[:, None], naj[:, None], dx[:, None], dy[:, None]
        c0, s0 = np.cos(th), np.sin(th)
        c1, s1 = np.cos(nth), np.sin(nth)
        t0x, t0y = x + (aj + 0.5 * gw) * c0, y + (aj + 0.5 * gw) * s0
        t1x, t1y = x + dx + (naj + 0.5 * gw) * c1, y + dy + (naj + 0.5 * gw) * s1
        rot = nth - th
        cr, sr = np.cos(rot), np.sin(rot)
        pidx = self._pose_idx
        pose = new[rows[:, None, None], pidx[None]]
        rx, ry = pose[..., 0] - t0x, pose[..., 1] - t0y
        moved = np.stack(
            [
                t1x + cr * rx - sr * ry,
                t1y + sr * rx + cr * ry,
                np.mod(pose[..., 2] + rot + np.pi, 2 * np.pi) - np.pi,
            ],
            -1,
        )
        new[rows[:, None, None], pidx[None]] = np.where(held[..., None], moved, pose)

    def _collides(
        self,
        new: FloatArray,
        robot: FloatArray,
        moving: BoolArray,
        rows: IntArray,
        old_obbs: FloatArray,
        old_circ: FloatArray,
    ) -> BoolArray:
        """``(N,)``: does the robot of ``new`` (its features ``robot``, ``(9, N)``), or a
        ``moving`` object (only sub-envs ``rows`` have any), collide with a static body or a
        non-moving object (``_moving_collides``)?

        The obstacles are the static bodies and the movable objects' bodies before the step
        (the non-moving ones have not moved). Only the (mover, obstacle) pairs whose obstacle
        passes the single env's broad phase and whose layers may collide get the exact test.
        """
        n = len(new)
        x, y, _, br, aj, _, _, gh, gw = robot
        reach = np.maximum(br, py_hypot(aj + 0.5 * gw, 0.5 * gh))
        box = np.stack([x - reach, x + reach, y - reach, y + reach], -1)
        m_obb = moving[:, self._obb_owner]
        m_circ = moving[:, self._circ_owner]
        new_obbs = new_circ = np.zeros((0, 0, 6))
        if rows.size:
            new_obbs, new_circ = self.movable_bodies(new[rows])
            lo = np.concatenate([obbs_aabb(new_obbs), circles_aabb(new_circ)], axis=1)
            mask = np.concatenate([m_obb[rows], m_circ[rows]], axis=1)[..., None]
            b = box[rows]
            b[:, 0::2] = np.minimum(b[:, 0::2], np.where(mask, lo[..., 0::2], np.inf).min(axis=1))
            b[:, 1::2] = np.maximum(b[:, 1::2], np.where(mask, lo[..., 1::2], -np.inf).max(axis=1))
            box[rows] = b
        if self.num_movable:
            obst_obbs = np.concatenate([self.static_obbs, old_obbs], axis=1)
            obst_circ = np.concatenate([self.static_circles, old_circ], axis=1)
            keep_obb = ~m_obb & self._m_collidable_obb
            keep_circ = ~m_circ & self._m_collidable_circ
            cand_obb = np.concatenate(
                [
                    aabb_hits(self.static_obb_aabb, box),
                    aabb_hits(obbs_aabb(old_obbs), box) & keep_obb,
                ],
                axis=1,
            )
            cand_circ = np.concatenate(
                [
                    aabb_hits(self.static_circ_aabb, box),
                    aabb_hits(circles_aabb(old_circ), box) & keep_circ,
                ],
                axis=1,
            )
        else:
            obst_obbs, obst_circ = self.static_obbs, self.static_circles
            cand_obb = aabb_hits(self.static_obb_aabb, box)
            cand_circ = aabb_hits(self.static_circ_aabb, box)
        hit = np.zeros(n, dtype=bool)
        # The robot's exact tests, only for sub-envs with a candidate obstacle.
        near = np.flatnonzero(cand_obb.any(axis=1) | cand_circ.any(axis=1))
        if near.size:
            ro, rc = self.robot_bodies(robot[:, near].T)
            _hits(
                hit,
                near,
                ro,
                None,
                rc,
                None,
                obst_obbs[near],
                cand_obb[near],
                obst_circ[near],
                cand_circ[near],
                self._may_robot,
            )
        if rows.size:
            _hits(
                hit,
                rows,
                new_obbs,
                m_obb[rows],
                new_circ,
                m_circ[rows],
                obst_obbs[rows],
                cand_obb[rows],
                obst_circ[rows],
                cand_circ[rows],
                self._may_movable,
            )
        return hit


@dataclass(frozen=True)
class _MayTable:
    """May-collide tables ``(mover bodies, obstacle bodies)`` for the four shape pairings."""

    obb_obb: BoolArray
    obb_circ: BoolArray
    circ_obb: BoolArray
    circ_circ: BoolArray


def _circle_obb_pairs(circles: FloatArray, boxes: FloatArray) -> BoolArray:
    """Mover circles against obstacle boxes: the box–circle kernel takes the box first."""
    return obb_circle_pairs(boxes, circles)


def _hits(
    hit: BoolArray,
    rows: IntArray,
    mo: FloatArray,
    mo_mask: BoolArray | None,
    mc: FloatArray,
    mc_mask: BoolArray | None,
    oo: FloatArray,
    oo_cand: BoolArray,
    oc: FloatArray,
    oc_cand: BoolArray,
    may: _MayTable,
) -> None:
    """Set ``hit[rows[k]]`` where a mover body of row ``k`` (boxes ``mo``, circles ``mc``; only
    those in the masks, all when None) collides with a candidate obstacle body of row ``k``
    (boxes ``oo``, circles ``oc``) whose layer it may collide with.

    Each pair gets the single env's kernel with the same argument order as ``bodies_collide``
    (mover, obstacle), except box–circle pairs, which the kernel takes as (box, circle).
    """
    for movers, m_mask, obst, o_cand, table, test in (
        (mo, mo_mask, oo, oo_cand, may.obb_obb, obb_obb_pairs),
        (mo, mo_mask, oc, oc_cand, may.obb_circ, obb_circle_pairs),
        (mc, mc_mask, oo, oo_cand, may.circ_obb, _circle_obb_pairs),
        (mc, mc_mask, oc, oc_cand, may.circ_circ, circle_circle_pairs),
    ):
        if not (movers.shape[1] and obst.shape[1]):
            continue
        pairs = o_cand[:, None, :] & table[None]
        if m_mask is not None:
            pairs &= m_mask[:, :, None]
        r, i, j = np.nonzero(pairs)
        if r.size:
            ok = test(movers[r, i], obst[r, j])
            hit[rows[r[ok]]] = True
