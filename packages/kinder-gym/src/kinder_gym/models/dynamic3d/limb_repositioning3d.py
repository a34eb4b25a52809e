"""The LimbRepositioning3D planning model: drive the welded human limb to its goal configuration.

The task (:mod:`kinder_garden3d.limb3d.env`): the gripper is welded to the grasp frame of a
passive limb; the action is the 7 arm torques (at most 1 N m each); the goal is the limb's six
joints within 0.1 rad (summed) of the goal configuration the state carries.

Concepts: ``AtGoal(robot, limb)`` (the env's own goal test) and ``NotAtGoal``. Goal:
``AtGoal(robot, limb)``.

Operator and skill: ``RepositionLimb(?robot, ?limb)`` (pre NotAtGoal; add AtGoal; delete
NotAtGoal). The controller plans in the limb's joint space and tracks in the arm's: the straight
joint-space path from the limb's configuration to the goal (continuous joints wrapped) is cut
into waypoints at most :data:`WAYPOINT_STEP` rad apart, each waypoint is turned into the arm
configuration that holds the grasp there (the env's grasp IK, started from the previous
waypoint's solution only, so that the arm stays on its branch), and a joint-space PD law (gains
:data:`KP`, :data:`KD`, clipped to the torque bounds) tracks that arm path, one waypoint per
``hold`` steps, then holds the last one. Turning the arm path into the limb path relies on the
weld: the limb follows the gripper, and from nearby waypoints it stays on the branch it started
on. The skill fails at once when a waypoint's grasp cannot be held (IK off by more than
:data:`MAX_IK_ERROR`), e.g. where the reset's grasp IK itself missed.

Measured (``kinder bench run -a bilevel_planning -e LimbRepositioning3D-<variant> --seeds
1000-1004 --episodes 10``, development seeds): isolated-left-arm and isolated-right-arm 1.00
(inference 0.9 s and 0.8 s an episode), isolated-right-leg 0.86 (no plan found; on the draw
traced, the reset's grasp IK had missed by 9 cm, so no arm path held the grasp). At 5 × 2:
isolated-left-leg 0.00 (the goal configuration's grasp lies 5.3 cm beyond the arm's reach,
upstream's own IK at its placement: 5.1 cm, and tracking the closest arm configuration leaves
the limb 0.9 to 3.9 rad from the goal on seeds 1000–1005); human-left-arm,
wheelchair-left-arm, wheelchair-right-arm and bed-left-arm 1.00; human-right-leg 0.80;
bed-left-leg 0.00 (its knee starts nearly straight, 0.18 rad, and the tracked arm path takes
the leg to another branch, 3.3 rad from the goal).

Differences from upstream: upstream kindergarden 0.2.5 has no LimbRepositioning3D planning
model; this one is new. Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.limb3d.env import LIMB_TYPE, ROBOT_TYPE, LimbRepositioning3DEnv
from kinder_gym.concepts import Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import first_objects_goal, goal_operator, goal_predicates
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import Controller, Skill, SkillFailure

#: Largest joint change (rad) of the limb between two waypoints.
WAYPOINT_STEP = 0.05
#: PD gains on the arm joints (N m per rad, N m per rad/s).
KP = 20.0
KD = 3.0
#: Steps per waypoint at the parameter's ends.
HOLD_RANGE = (20, 60)
#: Largest gripper position error (m) of a waypoint's grasp IK (the wheelchair-right-arm goal
#: grasp is 5 mm out of reach, and tracking it still brings the limb within the tolerance).
MAX_IK_ERROR = 0.01
#: Feature slices of the robot (arm joints, velocities) and the limb (joints, goal).
_ARM = slice(3, 10)
_ARM_VEL = slice(10, 17)
_LIMB = slice(0, 6)
_GOAL = slice(12, 18)


def _wrap(x: FloatArray) -> FloatArray:
    return np.asarray((x + math.pi) % (2.0 * math.pi) - math.pi, dtype=np.float64)


class RepositionLimbController(Controller):
    """Track an arm path that carries the limb to its goal. Objects: ``(robot, limb)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = (
        "(u,): the pace; each waypoint (at most 0.05 rad of limb motion) is tracked for "
        "20 + 40·u steps before the next."
    )

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        env: LimbRepositioning3DEnv = self.context
        robot, limb = self.objects
        start = np.asarray(state[limb][_LIMB], dtype=np.float64)
        delta = _wrap(np.asarray(state[limb][_GOAL], dtype=np.float64) - start)
        n = max(1, math.ceil(float(np.max(np.abs(delta))) / WAYPOINT_STEP))
        arm = tuple(float(q) for q in state[robot][_ARM])
        self._path: list[FloatArray] = []
        for i in range(1, n + 1):
            q, err = env.grasp_arm_joints(start + delta * (i / n), first=arm, only_first=True)
            if err > MAX_IK_ERROR:
                raise SkillFailure(
                    f"no arm configuration holds the grasp at waypoint {i}/{n} ({err:.3f} m off)"
                )
            self._path.append(q)
            arm = tuple(float(v) for v in q)
        lo, hi = HOLD_RANGE
        self._hold = round(lo + (hi - lo) * float(self.params[0]))
        self._k = 0
        self._high = np.asarray(env.action_space.high, dtype=np.float64)

    def step(self) -> FloatArray:
        assert self.state is not None
        robot = self.objects[0]
        ref = self._path[min(self._k // self._hold, len(self._path) - 1)]
        q = np.asarray(self.state[robot][_ARM], dtype=np.float64)
        dq = np.asarray(self.state[robot][_ARM_VEL], dtype=np.float64)
        self._k += 1
        return np.clip(KP * _wrap(ref - q) - KD * dq, -self._high, self._high)

    def terminated(self) -> bool:
        return self.state is not None and bool(self.context.goal_reached(self.state))


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The LimbRepositioning3D planning model (every scene and limb)."""
    if not isinstance(env, LimbRepositioning3DEnv):
        raise TypeError(f"expected a LimbRepositioning3DEnv, got {type(env).__name__}")

    def at_goal(state: ObjectCentricState, objs: Sequence[Object]) -> bool:
        del objs
        return bool(env.goal_reached(state))

    AtGoal, NotAtGoal = goal_predicates("AtGoal", (ROBOT_TYPE, LIMB_TYPE), at_goal)
    r = Variable("?robot", ROBOT_TYPE)
    limb = Variable("?limb", LIMB_TYPE)
    move = goal_operator("RepositionLimb", (r, limb), AtGoal, NotAtGoal, (r, limb))
    steps = env.spec.max_episode_steps if env.spec is not None else None
    return PlanningModel(
        name="limbrepositioning3d",
        env=env,
        types=(ROBOT_TYPE, LIMB_TYPE),
        predicates=(AtGoal, NotAtGoal),
        skills=(Skill(move, RepositionLimbController, env),),
        goal_fn=first_objects_goal(AtGoal),
        objects_fn=lambda state: [env.robot, env.limb],
        max_skill_horizon=steps or 2400,
        max_episode_steps=steps,
    )


__all__: Sequence[str] = ["RepositionLimbController", "create_model"]
