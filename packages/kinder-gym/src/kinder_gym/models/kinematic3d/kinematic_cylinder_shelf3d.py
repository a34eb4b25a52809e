"""The KinematicCylinderShelf3D planning model: side-grasp every cylinder off the floor and stand
it on a shelf board.

Upstream has no planning model for this family. Concepts (over the cylinders):

* ``HandEmpty(robot)`` / ``Holding(robot, cylinder)``.
* ``OnFloor(cylinder)``: not held and not standing on the shelf.
* ``OnShelf(cylinder)``: not held, standing on a board inside the shelf's footprint (the env's
  goal test for one cylinder).

Operators: ``Pick(?robot, ?cylinder)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty,
OnFloor) and ``Place(?robot, ?cylinder)`` (pre Holding; add HandEmpty, OnShelf; delete Holding).
Goal: every cylinder ``OnShelf`` and ``HandEmpty``.

Skills, both with the gripper horizontal (a side grasp: the approach axis is level and the
fingers close horizontally, so any approach angle around a cylinder works):

* Pick (:class:`SidePickController`): retract, drive to a standoff facing the cylinder, reach a
  point ``SIDE_APPROACH`` short of the grasp along the approach, move in, close, lift straight up.
* Place (:class:`SidePlaceController`): retract (carrying the cylinder upright), drive to a
  standoff in front of the shelf, reach ``SIDE_APPROACH`` in front of the release pose, move in
  until the cylinder stands 3 mm above a sampled spot on a sampled board, open, back out.

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.geometry import compose
from kinder_garden3d.kinematic3d.kinematic_cylinder_shelf3d import KinematicCylinderShelf3DConfig
from kinder_gym.model import PlanningModel
from kinder_gym.models.kinematic3d.pick_release import board_spot, floor_pick_model
from kinder_gym.models.kinematic3d.tidybot import (
    ConfigWaypoint,
    ReachController,
    bounds_around,
    release_pose,
)
from kinder_gym.motion_planning import FloatArray

#: How far short of the grasp (or release) pose the gripper stops before moving in (m).
SIDE_APPROACH = 0.06
#: How far a picked cylinder is lifted straight up (m).
LIFT = 0.1
#: The gripper frame to the tool frame: a quarter turn about the approach axis (x, y, z, w), the
#: inverse of the tool-to-gripper turn that :func:`tool_to_pinch` applies.
_GRIPPER_TO_TOOL = np.array([0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)])


def side_quat(heading: float) -> FloatArray:
    """The pinch orientation (x, y, z, w) with the approach axis level along ``heading`` and the
    fingers closing horizontally: a quarter turn about y, then ``heading`` about world z."""
    c, s = math.cos(heading / 2), math.sin(heading / 2)
    h = math.sqrt(0.5)
    # Rz(heading) ⊗ Ry(π/2): (0, 0, s, c) ⊗ (0, h, 0, h).
    return np.array([-s * h, c * h, s * h, c * h])


class _SideController(ReachController):
    """Retract, drive, reach in front of a pose along a level approach, move in, act, back out
    (or lift). Objects: ``(robot, cylinder)``."""

    def planning_bounds(self, state: ObjectCentricState) -> tuple[float, float, float, float]:
        """The robot, the cylinders and the shelf, grown by ``PLANNING_MARGIN``."""
        sx, sy, _ = self.env_config(KinematicCylinderShelf3DConfig).shelf_pos
        return bounds_around(super().planning_bounds(state), sx, sy)

    def _side_sequence(
        self,
        state: ObjectCentricState,
        base_goal: FloatArray,
        pinch_p: FloatArray,
        pinch_q: FloatArray,
        heading: float,
        gripper: float,
        salt: int,
    ) -> list[ConfigWaypoint]:
        """Retract, drive, reach ``SIDE_APPROACH`` short of the pinch pose along ``heading``,
        move in, send ``gripper``; a pick (``gripper < 0``) then lifts the cylinder ``LIFT``
        straight up, a place backs out of the shelf."""
        back = np.array([math.cos(heading), math.sin(heading), 0.0]) * SIDE_APPROACH
        lift = np.array([0.0, 0.0, LIFT]) if gripper < 0 else None
        return self._sequence(
            state, base_goal, pinch_p, pinch_q, gripper, salt, approach=-back, lift=lift
        )


class SidePickController(_SideController):
    """Side-grasp a cylinder standing on the floor. Objects: ``(robot, cylinder)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(dist, angle, height): the base stands 0.75 + 0.1·dist metres from the cylinder's "
        "axis, approaching from (angle − 0.5)·π/2 radians off the line from the robot to the "
        "cylinder; the fingers close 2 + 2·height cm below its top."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.robot, "grasp_active") < 0.5

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, obj = self.objects
        dist_p, angle_p, height_p = (float(p) for p in self.params)
        f = state[obj]
        base = np.asarray(state[robot][:2], dtype=np.float64)
        heading = math.atan2(f[1] - base[1], f[0] - base[0]) + (angle_p - 0.5) * math.pi / 2
        # Near the top: a level gripper reaches low points only at a narrow range of distances.
        top = float(f[2] + f[11])
        grasp = np.array([f[0], f[1], top - 0.02 - 0.02 * height_p])
        dist = 0.75 + 0.1 * dist_p
        base_goal = self._standoff(state, grasp, dist, heading)
        return self._side_sequence(
            state, base_goal, grasp, side_quat(heading), heading, -1.0, salt=1
        )


class SidePlaceController(_SideController):
    """Stand the held cylinder on a shelf board. Objects: ``(robot, cylinder)``."""

    params_space = spaces.Box(0.0, 1.0, (4,), dtype=np.float64)
    params_doc = (
        "(u, v, dist, board): the cylinder stands at fractions (u, v) of the board (shrunk by "
        "its radius and 2 cm), 3 mm above it, on the board picked by ``board`` among those whose "
        "clear height fits it; the base stands 0.7 + 0.15·dist metres in front of the spot."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "grasp_active") > 0.5

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, obj = self.objects
        u, v, dist_p, board_p = (float(p) for p in self.params)
        cfg = self.env_config(KinematicCylinderShelf3DConfig)
        shelf = cfg.shelf
        sz = cfg.shelf_pos[2]
        f = state[obj]
        radius, half_h = float(f[9]), float(f[11])
        tops = shelf.surface_heights(sz)
        # Boards with room above for the cylinder and the gripper (the top board has no limit).
        fits = [
            k
            for k, top in enumerate(tops)
            if k + 1 == len(tops) or tops[k + 1] - shelf.board_thickness - top > 2 * half_h + 0.02
        ]
        top = tops[fits[min(len(fits) - 1, int(board_p * len(fits)))]]
        x, y = board_spot(shelf, cfg.shelf_pos, u, v, radius + 0.02)
        spot = np.array([x, y, top + half_h + 0.003])
        heading = math.pi / 2  # from the front of the shelf (−y), facing +y
        pinch_q = side_quat(heading)
        tool_q = compose(np.zeros(3), pinch_q, np.zeros(3), _GRIPPER_TO_TOOL)[1]
        pinch_p, pinch_q = release_pose(state, robot, spot, tool_q)
        base_goal = self._standoff(state, pinch_p, 0.7 + 0.15 * dist_p, heading)
        return self._side_sequence(state, base_goal, pinch_p, pinch_q, heading, 1.0, salt=2)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The KinematicCylinderShelf3D planning model (any number of cylinders)."""
    cfg = env.config  # type: ignore[attr-defined]
    sx, sy, sz = cfg.shelf_pos
    tops = cfg.shelf.surface_heights(sz)

    def on_shelf(state: ObjectCentricState, c: Object) -> bool:
        """The env's goal test for one cylinder: inside the footprint, at its resting height
        on some board (within the env's tolerance)."""
        x, y, z = (float(v) for v in state[c][:3])
        if abs(x - sx) > cfg.shelf.width / 2 or abs(y - sy) > cfg.shelf.depth / 2:
            return False
        rest = float(state[c][11])
        return any(abs(z - (top + rest)) <= cfg.on_shelf_z_tolerance for top in tops)

    cylinders = list(env.cylinders)  # type: ignore[attr-defined]
    skills = (SidePickController, SidePlaceController)
    return floor_pick_model(
        env, "kinematic_cylinder_shelf3d", cylinders, "?cylinder", "OnShelf", on_shelf, skills
    )


__all__: Sequence[str] = ["SidePickController", "SidePlaceController", "create_model", "side_quat"]
