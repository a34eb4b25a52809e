"""The KinematicShelf3D planning model: pick every block off the floor onto the shelf's top board.

Upstream has no planning model for this family. Concepts (over the blocks):

* ``HandEmpty(robot)`` / ``Holding(robot, block)``.
* ``OnFloor(block)``: not held, centre below the env's on-shelf height.
* ``OnShelf(block)``: not held, centre at or above it (the env's goal test for one block).

Operators: ``Pick(?robot, ?block)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty,
OnFloor) and ``Place(?robot, ?block)`` (pre Holding; add HandEmpty, OnShelf; delete Holding).
Goal: every block ``OnShelf`` and ``HandEmpty`` (a release opens the gripper, which the env's
goal asks for).

Skills (motions collision-checked with the env's own pybullet geometry; OMPL for the base and the
arm; IK with the robot model's solver):

* Pick (:class:`~kinder_gym.models.kinematic3d.pick_release.BlockPickController`): Transport3D's
  pick, with the fingers closing across the block's narrow side (a block is 10 cm long, wider
  than the open gripper).
* Place (:class:`ShelfPlaceController`, a
  :class:`~kinder_gym.models.kinematic3d.pick_release.ReleaseController`): retract the arm
  (carrying the block), drive to a sampled standoff in front of (or behind) the shelf, reach
  above a sampled spot on the top board, descend until the block is 3 mm above it, open, lift.
  The top board is the one a top-down grasp can reach: the boards below it are only 0.254 m
  apart, less than the wrist needs.

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.kinematic_shelf3d import KinematicShelf3DConfig
from kinder_gym.model import PlanningModel
from kinder_gym.models.kinematic3d.pick_release import (
    BlockPickController,
    ReleaseController,
    board_spot,
    centre_at_least,
    floor_pick_model,
)
from kinder_gym.models.kinematic3d.tidybot import (
    ConfigWaypoint,
    bounds_around,
    release_pose,
    top_down_quat,
)


class ShelfPlaceController(ReleaseController):
    """Place the held block on the shelf's top board. Objects: ``(robot, block)``; the shelf is
    the env's."""

    params_space = spaces.Box(0.0, 1.0, (4,), dtype=np.float64)
    params_doc = (
        "(u, v, dist, side): the block's centre goes to fractions (u, v) of the top board "
        "(shrunk by the block's footprint radius and 2 cm), 3 mm above it; the base stands "
        "0.38 + 0.12·dist metres away, in front of the shelf (side < 1/2) or behind it."
    )

    def planning_bounds(self, state: ObjectCentricState) -> tuple[float, float, float, float]:
        """The robot, the blocks and the shelf, grown by ``PLANNING_MARGIN``."""
        sx, sy, _ = self.env_config(KinematicShelf3DConfig).shelf_pos
        return bounds_around(super().planning_bounds(state), sx, sy)

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, obj = self.objects
        u, v, dist_p, side = (float(p) for p in self.params)
        cfg = self.env_config(KinematicShelf3DConfig)
        shelf = cfg.shelf
        top = shelf.surface_heights(cfg.shelf_pos[2])[-1]
        o_half = np.asarray(state[obj][9:12], dtype=np.float64)
        r = float(np.hypot(o_half[0], o_half[1])) + 0.02
        px, py = board_spot(shelf, cfg.shelf_pos, u, v, r)
        pz = top + o_half[2] + 0.003
        angle = math.pi / 2 if side < 0.5 else -math.pi / 2
        dist = 0.38 + 0.12 * dist_p
        ee_p, ee_q = release_pose(state, robot, np.array([px, py, pz]), top_down_quat(angle))
        base_goal = self._standoff(state, np.array([px, py]), dist, angle)
        return self._place_sequence(state, base_goal, ee_p, ee_q)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The KinematicShelf3D planning model (any number of blocks)."""
    cfg = env.config  # type: ignore[attr-defined]
    on_shelf = centre_at_least(cfg.shelf_pos[2] + cfg.shelf.spacing - cfg.on_shelf_z_tolerance)
    cubes = list(env.cubes)  # type: ignore[attr-defined]
    skills = (BlockPickController, ShelfPlaceController)
    return floor_pick_model(env, "kinematic_shelf3d", cubes, "?block", "OnShelf", on_shelf, skills)


__all__: Sequence[str] = ["ShelfPlaceController", "create_model"]
