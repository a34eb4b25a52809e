"""The LimbRepositioning3D planning model: drive the welded human limb to its goal configuration.

The task (:mod:`kinder_garden3d.limb3d.env`): the gripper is welded to the grasp frame of a
passive limb; the action is the 7 arm torques (at most 1 N m each); the goal is the limb's six
joints within 0.1 rad (summed) of the goal configuration the state carries.

Concepts: ``AtGoal(robot, limb)`` (the env's own goal test) and ``NotAtGoal``. Goal:
``AtGoal(robot, limb)``.

Operator and skill: ``RepositionLimb(?robot, ?limb)`` (pre NotAtGoal; add AtGoal; delete
NotAtGoal). The controller plans in the limb's joint space and tracks in the arm's. The limb path
runs straight in joint space (continuous joints wrapped) from the limb's configuration to the goal,
through a via point :data:`VIA_FRACTION` of the way where the elbow or knee is bent up to
:data:`VIA_BEND` rad further (the parameter ``v``), cut into waypoints at most :data:`WAYPOINT_STEP`
rad apart. Each waypoint is turned into the arm configuration that holds the grasp there, near the
previous one so that the arm stays on its branch: the env's grasp IK started from the previous
waypoint's solution, else from it with the elbow bent :data:`ELBOW_NUDGE` either way (a straight
elbow bends equally well both ways), else pybullet's null-space IK within the arm's joint limits; a
solution may lie no further beyond a joint limit than the arm has since the path began, give or take
:data:`BEYOND_SLACK` (pybullet's IK ignores the limits, and an arm driven into a limit stops there
while the limb drifts). A joint-space PD law (gains :data:`KP`, :data:`KD`, clipped to the torque
bounds) tracks that arm path, moving on to the next waypoint once the limb is within
:data:`ADVANCE_TOL` of the current one (after :data:`MIN_HOLD` steps), or after ``hold`` steps (the
parameter ``u``), and holds the last one. Where the reset's grasp IK missed (the arm's joints do not
hold the grasp within :data:`MAX_IK_ERROR`), the weld first pulls the gripper onto the grasp frame:
the arm is damped for :data:`SETTLE_STEPS` steps and the path is planned from where the limb
settled. Turning the arm path into the limb path relies on the weld: the limb follows the gripper,
and from nearby waypoints it stays on the branch it started on, except near a straight knee, where
the bed's legs start (0.18 rad): there the straight path lets the knee bend backward (another
branch, 3.3 rad from the goal), and bending it further first keeps it on its branch. The skill fails
at once when a waypoint's grasp cannot be held (IK off by more than :data:`MAX_IK_ERROR`), e.g.
where the goal's grasp lies beyond the arm's reach.

Measured (BP, ``kinder bench campaign benchmarks/campaigns/extra_families.toml --only
dev/LimbRepositioning3D-<variant> --out runs/campaign/extra_families_limb2 --workers 1``,
development seeds 1000–1004 × 10 episodes, 2026-11-27; ``benchmarks/results/extra_families_bp.md``):
1.00 on the seven arms other than bed-right-arm and on bed-left-leg, bed-right-leg, human-left-leg,
human-right-leg and wheelchair-right-leg; isolated-right-leg 0.96 (the two failures: the
reset's grasp IK missed by 12 cm and 7 cm, and no arm path holds the grasp from where the limb
settles); 0.00 on bed-right-arm, isolated-left-leg and wheelchair-left-leg, whose goal grasps lie
17.7 cm, 5.3 cm (upstream's own IK: 5.1 cm) and 10.1 cm beyond the arm's reach from the
variant's robot placement (the grasp's position alone is reachable on the first two, not with
its orientation), so the skill fails at once.

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
from kinder_garden3d.robot.description import robot_description
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
#: Most steps per waypoint at the pace parameter's ends.
HOLD_RANGE = (20, 60)
#: Largest gripper position error (m) of a waypoint's grasp IK (the wheelchair-right-arm goal
#: grasp is 5 mm out of reach, and tracking it still brings the limb within the tolerance).
MAX_IK_ERROR = 0.01
#: The next waypoint is tracked once the limb is within ADVANCE_TOL (rad, every joint) of the
#: current one, after MIN_HOLD steps at least.
ADVANCE_TOL = 0.02
MIN_HOLD = 5
#: Steps the arm is damped for, where the reset's grasp IK missed, before the path is planned.
SETTLE_STEPS = 60
#: How much further (rad) beyond a joint limit than the previous waypoint's a waypoint's arm
#: configuration may lie (an arm that starts beyond a limit first moves along it).
BEYOND_SLACK = 0.01
#: The elbow's index among the arm joints, and how far (rad) the grasp IK's start is bent
#: either way when the solution from the arm's joints misses.
_ELBOW = 3
ELBOW_NUDGE = 0.3
#: The via point of the limb path: how far along, and the largest extra bend (rad) of the
#: elbow or knee (limb joint 4) there.
VIA_FRACTION = 0.3
VIA_BEND = 0.4
_BEND = 3
#: Feature slices of the robot (arm joints, velocities) and the limb (joints, goal).
_ARM = slice(3, 10)
_ARM_VEL = slice(10, 17)
_LIMB = slice(0, 6)
_GOAL = slice(12, 18)


def _wrap(x: FloatArray) -> FloatArray:
    return np.asarray((x + math.pi) % (2.0 * math.pi) - math.pi, dtype=np.float64)


def _beyond(q: FloatArray, low: FloatArray, high: FloatArray) -> FloatArray:
    """How far (rad) each joint of ``q`` lies beyond its limits (0 within them)."""
    return np.maximum(0.0, np.maximum(low - q, q - high))


def _segment(a: FloatArray, b: FloatArray) -> list[FloatArray]:
    n = max(1, math.ceil(float(np.max(np.abs(b - a))) / WAYPOINT_STEP))
    return [a + (b - a) * (i / n) for i in range(1, n + 1)]


def limb_path(start: FloatArray, goal: FloatArray, bend: float = 0.0) -> list[FloatArray]:
    """Limb waypoints from ``start`` (exclusive) to ``goal``, at most WAYPOINT_STEP apart:
    straight in joint space through a via point :data:`VIA_FRACTION` of the way, where the
    elbow or knee is bent ``bend`` rad further (toward the goal's bend) than on the line."""
    if bend <= 0.0:
        return _segment(start, goal)
    via = start + (goal - start) * VIA_FRACTION
    via[_BEND] += math.copysign(bend, goal[_BEND])
    return _segment(start, via) + _segment(via, goal)


class RepositionLimbController(Controller):
    """Track an arm path that carries the limb to its goal. Objects: ``(robot, limb)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(u, v): u, the pace: each waypoint (at most 0.05 rad of limb motion) is tracked until "
        "the limb is within 0.02 rad of it, for 20 + 40·u steps at most; v, the path: the "
        "elbow or knee is bent 0.4·v rad beyond the straight limb path 0.3 of the way along."
    )

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """A uniform pace; half the samples take the straight limb path (v = 0), the others
        bend the elbow or knee at the via point by 0.5 to 1 of :data:`VIA_BEND`."""
        del state
        v = 0.0 if rng.random() < 0.5 else float(rng.uniform(0.5, 1.0))
        return np.array([rng.uniform(0.0, 1.0), v], dtype=np.float64)

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        env: LimbRepositioning3DEnv = self.context
        lo, hi = HOLD_RANGE
        self._hold = round(lo + (hi - lo) * float(self.params[0]))
        self._k = 0
        self._high = np.asarray(env.action_space.high, dtype=np.float64)
        self._path: list[FloatArray] = []
        self._limbs: list[FloatArray] = []
        self._i = 0
        robot, limb = self.objects
        arm = tuple(float(q) for q in state[robot][_ARM])
        _, err = env.grasp_arm_joints(
            np.asarray(state[limb][_LIMB], dtype=np.float64), first=arm, only_first=True
        )
        # Where the reset's grasp IK missed, the weld first pulls the gripper onto the grasp
        # frame: damp the arm until that settles, then plan from where the limb ended up.
        self._settle = SETTLE_STEPS if err > MAX_IK_ERROR else 0
        if not self._settle:
            self._plan(state)

    def _plan(self, state: ObjectCentricState) -> None:
        """The arm path holding the grasp along the limb's path to its goal."""
        robot, limb = self.objects
        start = np.asarray(state[limb][_LIMB], dtype=np.float64)
        goal = start + _wrap(np.asarray(state[limb][_GOAL], dtype=np.float64) - start)
        arm = tuple(float(q) for q in state[robot][_ARM])
        low, high = robot_description().arm_joint_limits
        waypoints = limb_path(start, goal, VIA_BEND * float(self.params[1]))
        n = len(waypoints)
        # The arm may start beyond a joint limit (the reset's IK keeps its closest miss); a
        # waypoint's joints may not go further beyond than the previous waypoint's.
        beyond = _beyond(np.asarray(arm), low, high)
        for i, waypoint in enumerate(waypoints, 1):
            q, err = self._hold_grasp(waypoint, arm, low, high, beyond)
            if err > MAX_IK_ERROR:
                raise SkillFailure(
                    f"no arm configuration holds the grasp at waypoint {i}/{n} ({err:.3f} m off)"
                )
            beyond = np.minimum(beyond, _beyond(q, low, high))
            self._path.append(q)
            self._limbs.append(waypoint)
            arm = tuple(float(v) for v in q)

    def _hold_grasp(
        self,
        waypoint: FloatArray,
        arm: tuple[float, ...],
        low: FloatArray,
        high: FloatArray,
        beyond: FloatArray,
    ) -> tuple[FloatArray, float]:
        """The arm configuration near ``arm`` holding the grasp at ``waypoint``, and its error
        (inf where every try leaves the limits further): the grasp IK from ``arm``, then from
        ``arm`` with the elbow bent :data:`ELBOW_NUDGE` either way (at a straight elbow the
        two bends are equally near), then the null-space IK within the joint limits."""
        env: LimbRepositioning3DEnv = self.context
        best: tuple[FloatArray, float] = (np.asarray(arm, dtype=np.float64), math.inf)
        tries: list[tuple[tuple[float, ...], bool]] = [(arm, False)]
        for sign in (1.0, -1.0):
            bent = list(arm)
            bent[_ELBOW] += sign * ELBOW_NUDGE
            tries.append((tuple(bent), False))
        tries.append((arm, True))
        for start, within in tries:
            q, err = env.grasp_arm_joints(
                waypoint, first=start, only_first=True, within_limits=within
            )
            if np.any(_beyond(q, low, high) > beyond + BEYOND_SLACK):
                continue
            if err <= MAX_IK_ERROR:
                return q, err
            if err < best[1]:
                best = (q, err)
        return best

    def step(self) -> FloatArray:
        assert self.state is not None
        robot = self.objects[0]
        dq = np.asarray(self.state[robot][_ARM_VEL], dtype=np.float64)
        if self._settle:
            self._settle -= 1
            return np.clip(-KD * dq, -self._high, self._high)
        if not self._path:
            self._plan(self.state)
        limb = np.asarray(self.state[self.objects[1]][_LIMB], dtype=np.float64)
        if self._i < len(self._path) - 1:
            lag = float(np.max(np.abs(_wrap(limb - self._limbs[self._i]))))
            if (self._k >= MIN_HOLD and lag < ADVANCE_TOL) or self._k >= self._hold:
                self._i += 1
                self._k = 0
        ref = self._path[self._i]
        q = np.asarray(self.state[robot][_ARM], dtype=np.float64)
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
