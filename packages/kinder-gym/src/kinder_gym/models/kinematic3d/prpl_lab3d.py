"""The PrplLab3D planning model: pick every cube off the lab's floor and let go of it at
countertop height.

Upstream has no planning model for this family. Its env lets a held cube go anywhere (the lab
counts as every object's support) and its goal only asks every cube to be released no lower than
5 cm below the countertop's top, so a cube need not be put on the counter. Concepts:

* ``HandEmpty(robot)`` / ``Holding(robot, cube)``.
* ``OnFloor(cube)``: not held, centre below the goal height.
* ``Raised(cube)``: not held, centre at or above it (the env's goal test for one cube).

Operators: ``Pick(?robot, ?cube)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty,
OnFloor) and ``Raise(?robot, ?cube)`` (pre Holding; add HandEmpty, Raised; delete Holding).
Goal: every cube ``Raised`` and ``HandEmpty``.

Skills: the pick is KinematicShelf3D's
(:class:`~kinder_gym.models.kinematic3d.pick_release.BlockPickController`); the raise
(:class:`RaiseController`) lifts the cube, where the robot stands, to a sampled point in front of
the base at a sampled height above the goal height and opens. Imports kinder_garden3d (the
``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.prpl_lab3d import PrplLab3DConfig
from kinder_gym.model import PlanningModel
from kinder_gym.models.kinematic3d.pick_release import (
    BlockPickController,
    ReleaseController,
    centre_at_least,
    floor_pick_model,
)
from kinder_gym.models.kinematic3d.tidybot import (
    ConfigWaypoint,
    release_pose,
    top_down_quat,
)


class RaiseController(ReleaseController):
    """Lift the held cube where the robot stands and open. Objects: ``(robot, cube)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(reach, side, height): the cube's centre goes 0.35 + 0.2·reach metres from the base "
        "centre, (side − 0.5)·π/2 radians off the base's heading, 2 + 6·height cm above the goal "
        "height."
    )

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, _obj = self.objects
        reach, side, height = (float(p) for p in self.params)
        cfg = self.env_config(PrplLab3DConfig)
        x, y, yaw = (float(v) for v in state[robot][:3])
        heading = yaw + (side - 0.5) * math.pi / 2
        dist = 0.35 + 0.2 * reach
        goal_z = cfg.counter_top_z - cfg.goal_below_counter
        spot = np.array(
            [
                x + dist * math.cos(heading),
                y + dist * math.sin(heading),
                goal_z + 0.02 + 0.06 * height,
            ]
        )
        ee_p, ee_q = release_pose(state, robot, spot, top_down_quat(heading))
        return self._place_sequence(state, np.array([x, y, yaw]), ee_p, ee_q)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The PrplLab3D planning model (any number of cubes)."""
    cfg = env.config  # type: ignore[attr-defined]
    raised = centre_at_least(cfg.counter_top_z - cfg.goal_below_counter)
    cubes = list(env.cubes)  # type: ignore[attr-defined]
    skills = (BlockPickController, RaiseController)
    return floor_pick_model(
        env, "prpl_lab3d", cubes, "?cube", "Raised", raised, skills, place_name="Raise"
    )


__all__: Sequence[str] = ["RaiseController", "create_model"]
