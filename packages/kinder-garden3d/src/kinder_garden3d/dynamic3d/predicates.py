"""Goal predicates of the Dynamic3D tasks, evaluated on object-centric states (features only).

* ``on`` / ``in`` (the same test): the entity's centre ``(x, y, z)`` — for the robot its base
  ``(x, y, 0)`` — lies inside one of the region's boxes, expressed in the region's frame (which
  follows the target's pose from the state, a drawer's slide and a seesaw's hinge).
* ``balanced seesaw tol_deg``: ``|hinge_pos| <= tol``.
* ``and`` / ``or`` combine predicates; atoms sharing a region are tested in one vectorised step.

:meth:`GoalEvaluator.many` evaluates the goal on N states at once (the rows of an (N, D) array),
in whole-array numpy: planners that check thousands of predicted states per step (MBRL's
learned-model rollouts) call it through the env's ``goals_reached``. The single-state check is
the same code on one row, so the two give the same verdicts by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinder_core import ObjectCentricState
from kinder_core.state import StateLayout
from kinder_garden3d.dynamic3d.geometry import (
    Array,
    pose_matrices,
    pose_matrix,
    quat_to_matrix,
    quat_yaw,
    quats_to_matrices,
    quats_yaw,
    rot_axis,
    rot_z,
    rots_axis,
    rots_z,
)
from kinder_garden3d.dynamic3d.scene import RegionFrame
from kinder_garden3d.dynamic3d.taskfile import ROBOT, Goal, RegionSpec

_POSE = ["x", "y", "z", "qw", "qx", "qy", "qz"]


class Regions:
    """World transforms of regions and point-in-region tests for one env layout."""

    def __init__(
        self, frames: dict[str, RegionFrame], specs: dict[str, RegionSpec], layout: StateLayout
    ) -> None:
        self.frames = frames
        self.specs = specs
        self._pose_idx: dict[str, NDArray[np.intp]] = {}
        self._extra_idx: dict[str, int] = {}
        for rf in frames.values():
            if rf.kind == "ground":
                continue
            obj = layout.object_named(rf.target)
            self._pose_idx[rf.target] = layout.indices([obj], _POSE)[0]
            if rf.hinge is not None:
                self._extra_idx[rf.target] = layout.index(obj, "hinge_pos")
            if rf.drawer is not None:
                self._extra_idx[rf.drawer] = layout.index(layout.object_named(rf.drawer), "pos")

    def transform(self, state: ObjectCentricState, region: str) -> Array:
        """The region frame's 4x4 world transform in ``state``."""
        rf = self.frames[region]
        if rf.kind == "ground":
            return np.eye(4)
        pose = state.data[self._pose_idx[rf.target]]
        rot = quat_to_matrix(pose[3:7])
        if rf.align == "world":
            rot = np.eye(3)
        elif rf.align == "yaw":
            rot = rot_z(quat_yaw(pose[3:7]))
        base = pose_matrix(pose[:3], rot)
        if rf.hinge is not None:
            angle = float(state.data[self._extra_idx[rf.target]])
            h = rf.hinge
            return (
                base
                @ pose_matrix(h.pivot, rot_axis(h.axis, angle))
                @ pose_matrix(h.offset, np.eye(3))
            )
        local = rf.local
        if rf.drawer is not None:
            local = local.copy()
            local[:3, 3] += np.asarray(rf.drawer_axis) * float(
                state.data[self._extra_idx[rf.drawer]]
            )
        return base @ local

    def transforms(self, data: Array, region: str) -> Array:
        """(N, 4, 4): :meth:`transform` in each of the N states whose features are the rows of
        ``data``."""
        n = len(data)
        rf = self.frames[region]
        if rf.kind == "ground":
            return np.broadcast_to(np.eye(4), (n, 4, 4))
        pose = data[:, self._pose_idx[rf.target]]
        if rf.align == "world":
            rot = np.broadcast_to(np.eye(3), (n, 3, 3))
        elif rf.align == "yaw":
            rot = rots_z(quats_yaw(pose[:, 3:7]))
        else:
            rot = quats_to_matrices(pose[:, 3:7])
        base = pose_matrices(pose[:, :3], rot)
        if rf.hinge is not None:
            h = rf.hinge
            hinge = pose_matrices(
                np.broadcast_to(np.asarray(h.pivot, dtype=float), (n, 3)),
                rots_axis(h.axis, data[:, self._extra_idx[rf.target]]),
            )
            out: Array = base @ hinge @ pose_matrix(h.offset, np.eye(3))
            return out
        local = np.broadcast_to(rf.local, (n, 4, 4))
        if rf.drawer is not None:
            local = local.copy()
            local[:, :3, 3] += (
                np.asarray(rf.drawer_axis) * data[:, self._extra_idx[rf.drawer], None]
            )
        out = base @ local
        return out

    def contains(self, state: ObjectCentricState, region: str, points: Array) -> NDArray[np.bool_]:
        """Which of the (k, 3) world ``points`` lie inside the region."""
        inside: NDArray[np.bool_] = self.contains_many(
            state.data[None], region, np.asarray(points)[None]
        )[0]
        return inside

    def contains_many(self, data: Array, region: str, points: Array) -> NDArray[np.bool_]:
        """(N, k): :meth:`contains` of each state's (k, 3) world points, ``points`` (N, k, 3)."""
        t = self.transforms(data, region)
        return self._in_boxes((points - t[:, None, :3, 3]) @ t[:, :3, :3], region)

    def _in_boxes(self, local: Array, region: str) -> NDArray[np.bool_]:
        """Which points (the last axis: x, y, z in the region frame) lie in one of its boxes."""
        boxes = self.specs[region].boxes
        p = local[..., None, :]
        inside = (p >= boxes[:, :3]) & (p <= boxes[:, 3:])
        result: NDArray[np.bool_] = np.any(np.all(inside, axis=-1), axis=-1)
        return result


@dataclass(frozen=True)
class _Group:
    """Atoms of one region: point indices into ``state.data`` (k, 3); -1 means a literal 0."""

    region: str
    idx: NDArray[np.intp]


class GoalEvaluator:
    """A compiled goal expression (see the module docstring)."""

    def __init__(self, goal: Goal, regions: Regions, layout: StateLayout) -> None:
        self.regions = regions
        self._layout = layout
        self._source = goal
        self._root = self._compile(goal)

    def _point_idx(self, entity: str) -> list[int]:
        obj = self._layout.object_named(entity)
        if entity == ROBOT:
            return [
                self._layout.index(obj, "pos_base_x"),
                self._layout.index(obj, "pos_base_y"),
                -1,
            ]
        return [self._layout.index(obj, f) for f in ("x", "y", "z")]

    def _compile(self, node: Goal) -> tuple[object, ...]:
        op = node[0]
        if op in ("and", "or"):
            groups: dict[str, list[list[int]]] = {}
            others = []
            for child in node[1]:
                if child[0] in ("on", "in"):
                    groups.setdefault(child[2], []).append(self._point_idx(child[1]))
                else:
                    others.append(self._compile(child))
            packed = [_Group(r, np.array(ix, dtype=np.intp)) for r, ix in groups.items()]
            return (op, packed, others)
        if op in ("on", "in"):
            return ("and", [_Group(node[2], np.array([self._point_idx(node[1])]))], [])
        # balanced
        obj = self._layout.object_named(node[1])
        return ("balanced", self._layout.index(obj, "hinge_pos"), np.radians(node[2]))

    def __call__(self, state: ObjectCentricState) -> bool:
        return bool(self.many(state.data[None])[0])

    def many(self, data: Array) -> NDArray[np.bool_]:
        """(N,): the goal's truth in each state whose features (in the evaluator's layout) are
        a row of ``data``."""
        return self._eval_many(self._root, np.asarray(data, dtype=np.float64))

    def _eval_many(self, node: tuple[object, ...], data: Array) -> NDArray[np.bool_]:
        op = node[0]
        if op == "balanced":
            ok: NDArray[np.bool_] = np.abs(data[:, node[1]]) <= node[2]  # type: ignore[index]
            return ok
        groups, others = node[1], node[2]
        want_all = op == "and"
        acc = np.full(len(data), want_all)
        for g in groups:  # type: ignore[attr-defined]
            pts = np.where(g.idx >= 0, data[:, np.maximum(g.idx, 0)], 0.0)
            inside = self.regions.contains_many(data, g.region, pts)
            acc = acc & inside.all(axis=1) if want_all else acc | inside.any(axis=1)
        for child in others:  # type: ignore[attr-defined]
            ok = self._eval_many(child, data)
            acc = acc & ok if want_all else acc | ok
        return acc

    def atoms(self, state: ObjectCentricState) -> dict[str, bool]:
        """Truth of every atom of the goal, keyed like ``"on(cube1, goal_region)"``."""
        out: dict[str, bool] = {}

        def walk(node: Goal) -> None:
            if node[0] in ("and", "or"):
                for child in node[1]:
                    walk(child)
            elif node[0] == "balanced":
                idx = self._layout.index(self._layout.object_named(node[1]), "hinge_pos")
                single = ("balanced", idx, np.radians(node[2]))
                out[f"balanced({node[1]}, {node[2]:g})"] = bool(
                    self._eval_many(single, state.data[None])[0]
                )
            else:
                g = _Group(node[2], np.array([self._point_idx(node[1])]))
                out[f"{node[0]}({node[1]}, {node[2]})"] = bool(
                    self._eval_many(("and", [g], []), state.data[None])[0]
                )

        walk(self._source)
        return out
