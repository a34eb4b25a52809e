"""Controllers shared by the Kinematic3D models that move blocks (10 × 5 × 5 cm cuboids) and let
go of them high up: KinematicShelf3D and PrplLab3D.

* :class:`BlockPickController`: the mobile manipulator's pick
  (:class:`~kinder_gym.models.kinematic3d.tidybot.PickController`), with the fingers closing
  across the block's narrow side (a block is longer than the open gripper is wide).
* :class:`ReleaseController`: retract, drive, reach a little above a release pose, descend, open
  and lift; families give the release pose.

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from kinder_core import ObjectCentricState
from kinder_gym.models.kinematic3d.tidybot import (
    HOME,
    ConfigChecker,
    ConfigWaypoint,
    PickController,
    ReachController,
    arm_path,
    base_path,
    config_delta,
    solve_ik,
    top_down_quat,
    wrap,
    yaw_of,
)
from kinder_gym.motion_planning import params_seed, segment_valid
from kinder_gym.skills import SkillFailure

#: How far above the release pose the place reaches first (m). Shorter than the pick's
#: approach: the release pose is near the top of the arm's top-down reach (about 0.92 m).
PLACE_APPROACH = 0.05


class BlockPickController(PickController):
    """Pick a block off the floor from a sampled standoff, the fingers closing across its
    narrower horizontal side. Objects: ``(robot, block)``."""

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, obj = self.objects
        dist = 0.45 + 0.2 * float(self.params[0])
        f = state[obj]
        pos = np.asarray(f[:3], dtype=np.float64)
        base = np.asarray(state[robot][:2], dtype=np.float64)
        angle = math.atan2(pos[1] - base[1], pos[0] - base[0]) + (float(self.params[1]) - 0.5) * (
            math.pi
        )
        obj_yaw = yaw_of(np.asarray(f[3:7]))
        # The fingers close along ee_yaw + π/2; across the block's y side when it is the
        # narrower one (ee_yaw = obj_yaw or obj_yaw + π), else across its x side.
        close_dir = obj_yaw + (math.pi / 2 if f[10] <= f[9] else 0.0)
        candidates = [close_dir - math.pi / 2 + k * math.pi for k in (0, 1)]
        ee_yaw = min(candidates, key=lambda y: abs(wrap(y - angle)))
        base_goal = self._standoff(state, pos, dist, angle)
        return self._sequence(state, base_goal, pos, top_down_quat(ee_yaw), -1.0, salt=1)


class ReleaseController(ReachController):
    """Carry the held object to a release pose and open: retract, drive, reach
    ``PLACE_APPROACH`` above the pose, descend, open, lift (the shared reach sequence with a
    shorter approach). Objects: ``(robot, object)``."""

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "grasp_active") > 0.5

    def _place_sequence(
        self,
        state: ObjectCentricState,
        base_goal: np.ndarray,
        ee_pos: np.ndarray,
        ee_quat: np.ndarray,
    ) -> list[ConfigWaypoint]:
        """Retract, drive, reach ``PLACE_APPROACH`` above the release pose, descend, open, lift
        (the shared reach sequence with a shorter approach)."""
        checker = ConfigChecker(self.context, state)
        q = np.asarray(state[self.robot][:10], dtype=np.float64)
        seed = params_seed(self.params, 2)
        wps: list[ConfigWaypoint] = []
        if np.max(np.abs(config_delta(q[3:], HOME))) > 1e-6:
            path = arm_path(checker, q, HOME, seed)
            wps += [self._wp(p) for p in path]
            q = path[-1]
        if np.max(np.abs(config_delta(q[:3], base_goal))) > 1e-6:
            path = base_path(checker, q, base_goal, self.planning_bounds(state), seed)
            wps += [self._wp(p) for p in path]
            q = path[-1]
        above = solve_ik(ee_pos + np.array([0.0, 0.0, PLACE_APPROACH]), ee_quat, q[:3], HOME)
        at = solve_ik(ee_pos, ee_quat, q[:3], above)
        q_above = np.concatenate([q[:3], above])
        q_at = np.concatenate([q[:3], at])
        wps += [self._wp(p) for p in arm_path(checker, q, above, seed + 1)]
        if not segment_valid(q_above, q_at, checker, np.full(10, 0.05)):
            raise SkillFailure(f"{type(self).__name__}: the final approach collides")
        wps.append(self._wp(q_at, 1.0))
        wps.append(self._wp(q_above))
        return wps


__all__: Sequence[str] = ["PLACE_APPROACH", "BlockPickController", "ReleaseController"]
