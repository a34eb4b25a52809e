"""The DynPushPullHook2D planning model: grasp the hook, reach over the target, pull it down.

The hook is an L: a long bar (``length_side1``) from its outer corner along local −x and a short
arm (``length_side2``) along local −y. The robot grasps the long bar at its free end, pointing
along the bar (the fingers close across it), then turns to face up (+y): the long bar then stands
upright above the robot with the short arm at its top pointing right, like a rake. The robot
raises the rake beside the target (left of it), slides the short arm over the target's top, and
drives straight down: the short arm drags the target onto the middle wall.

Concepts:

* ``HandEmpty(robot)`` / ``HoldingHook(robot, hook)``: the hook is (not) held.
* ``HookAbove(hook, target)``: the hook is held and its short arm lies over the target (its lower
  edge above the target's top, its x-range covering the target's centre).
* ``TargetAtGoal(target)``: the env's goal test (the target overlaps the middle wall).

Operators: ``GraspHook(?robot, ?hook)`` (pre HandEmpty; add HoldingHook; delete HandEmpty),
``PreHook(?robot, ?hook, ?target)`` (pre HoldingHook; add HookAbove), ``HookDown(?robot, ?hook,
?target)`` (pre HoldingHook, HookAbove; add TargetAtGoal; delete HookAbove). Goal:
``TargetAtGoal(target_block)``.

Obstructions are not part of the abstraction: the held hook (infinite mass) pushes them aside.

GraspHook's arm length is capped so that the approach pose, on the bar's axis beyond its free
end, keeps the base inside the room below the middle wall; when the route to the spot where the
robot turns to face the bar touches something, it tries other spots (nearest first). What limits
the model (``benchmarks/results/bilevel_planning.md``, "DynPushPullHook2D: where planning
fails"): the bar is taken only at its free end, so when that end lies near the left wall there is
no room for the robot at any arm length (about a third of the instances); the rake comes from the
target's left, so a target near the left wall cannot be raked.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_garden2d.dynamic2d.geometry import (
    WorldShape,
    bounds,
    kin_robot_geometry,
    lobject_shape,
    overlaps,
    place,
    rect_shape,
    transform,
)
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic2d.kin_robot import (
    ARM_LENGTH,
    BASE_RADIUS,
    FINGER_HEIGHT,
    FINGER_WIDTH,
    GRIPPER_BASE_HEIGHT,
    GRIPPER_BASE_WIDTH,
    KinRobotController,
    KinWaypoint,
    kin_config,
    wrap,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.operators import LiftedOperator
from kinder_gym.skills import Skill, SkillFailure

UP = math.pi / 2
#: Grid spots GraspHook tries for turning to face the bar when the fixed spot does not work.
TURNING_SPOTS = 12


def hook_shape(state: ObjectCentricState, hook: Object) -> WorldShape:
    """The hook's two boxes in the world."""
    h = state[hook]
    w, s1, s2 = (state.get(hook, k) for k in ("width", "length_side1", "length_side2"))
    return place(lobject_shape(w, s1, s2), h[0], h[1], h[2])


def short_arm(state: ObjectCentricState, hook: Object) -> FloatArray:
    """The short arm's corners in the world (4×2)."""
    h = state[hook]
    w, s2 = state.get(hook, "width"), state.get(hook, "length_side2")
    local = np.array([[-w, -s2], [0.0, -s2], [0.0, 0.0], [-w, 0.0]])
    return np.asarray(transform(local, h[0], h[1], h[2]))


def block_corners(state: ObjectCentricState, block: Object) -> FloatArray:
    """A rectangle block's corners in the world (4×2)."""
    b = state[block]
    w, h = state.get(block, "width"), state.get(block, "height")
    return np.asarray(transform(rect_shape(w, h).polys[0], b[0], b[1], b[2]))


def hook_above(state: ObjectCentricState, hook: Object, target: Object) -> bool:
    """``HookAbove``: held, short arm over the target (see the module docstring)."""
    if state.get(hook, "held") < 0.5:
        return False
    arm = short_arm(state, hook)
    tgt = block_corners(state, target)
    cx = float(np.mean(tgt[:, 0]))
    return bool(
        arm[:, 1].min() >= tgt[:, 1].max() - 0.02 and arm[:, 0].min() <= cx <= arm[:, 0].max()
    )


class _HookController(KinRobotController):
    """Shared collision checks (robot and held hook against blocks and walls)."""

    def _robot_shape(self, state: ObjectCentricState, q: Sequence[float]) -> WorldShape:
        vec = state[self.robot].copy()
        vec[0], vec[1], vec[2], vec[17], vec[21] = q[0], q[1], q[2], q[3], q[4]
        return kin_robot_geometry(vec).shape

    def _touches(
        self, state: ObjectCentricState, q: Sequence[float], ignore: Sequence[Object]
    ) -> str | None:
        """What the robot at ``q`` would touch (None when nothing)."""
        env = self.context
        cfg = env.config
        shape = self._robot_shape(state, q)
        x0, x1, y0, y1 = bounds(shape)
        if (
            x0 <= cfg.world_min_x
            or x1 >= cfg.world_max_x
            or y0 <= cfg.world_min_y
            or (y1 >= cfg.world_max_y)
        ):
            return "a wall"
        mid = (cfg.world_min_y + cfg.world_max_y) / 2
        if q[1] + state[self.robot][BASE_RADIUS] >= mid - cfg.wall_height / 2:
            return "the middle wall"
        for o in state.get_objects(ot.DYNAMIC2D_OBJECT):
            if o in ignore or o == self.robot:
                continue
            if o.type.is_subtype_of(ot.LOBJECT):
                other = hook_shape(state, o)
            else:
                f = state[o]
                other = place(rect_shape(state.get(o, "width"), state.get(o, "height")), *f[:3])
            if overlaps(shape, other):
                return o.name
        return None

    def _check_segment(
        self,
        state: ObjectCentricState,
        a: Sequence[float],
        b: Sequence[float],
        ignore: Sequence[Object],
    ) -> None:
        n = max(1, math.ceil(max(abs(b[0] - a[0]), abs(b[1] - a[1])) / 0.05))
        for k in range(1, n + 1):
            q = [a[i] + (b[i] - a[i]) * k / n for i in range(5)]
            hit = self._touches(state, q, ignore)
            if hit is not None:
                raise SkillFailure(f"{type(self).__name__}: the robot would touch {hit}")


class GraspHookController(_HookController):
    """Grasp the hook's long bar at its free end. Objects: ``(robot, hook)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(overlap, arm): the fingers cover 0.06 + 0.1·overlap metres of the bar's end; the arm "
        "is extended to base_radius + arm·(longest − base_radius) metres, where longest is "
        "arm_length or less: the longest arm with which the approach pose, on the bar's axis "
        "beyond its free end, keeps the base inside the room below the middle wall."
    )

    def waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        robot, hook = self.objects
        v = state[robot]
        br, al = float(v[BASE_RADIUS]), float(v[ARM_LENGTH])
        gw, fw, fh = float(v[GRIPPER_BASE_WIDTH]), float(v[FINGER_WIDTH]), float(v[FINGER_HEIGHT])
        open_gap = float(v[GRIPPER_BASE_HEIGHT])
        overlap = 0.06 + 0.1 * float(self.params[0])
        hx, hy, hth = (float(c) for c in state[hook][:3])
        w, s1 = state.get(hook, "width"), state.get(hook, "length_side1")
        c, s = math.cos(hth), math.sin(hth)

        def world(lx: float, ly: float) -> tuple[float, float]:
            return hx + c * lx - s * ly, hy + s * lx + c * ly

        # The approach comes along the bar's axis from beyond its free end: near a wall only a
        # shorter arm leaves the base room there.
        end_x, end_y = world(-s1, -w / 2)
        longest = min(al, self._room_beyond(end_x, end_y, -c, -s, br) - 0.06 - gw / 2 - fw)
        if longest < br:
            raise SkillFailure("GraspHook: no room for the robot beyond the bar's free end")
        arm = br + float(self.params[1]) * (longest - br)
        reach = arm + gw / 2 + fw
        gx, gy = world(-s1 + overlap - reach, -w / 2)
        # Pre-grasp: the fingertips 0.06 m short of the bar's end, on its axis.
        px, py = world(-s1 - 0.06 - reach, -w / 2)
        q = kin_config(state, robot)
        close_gap = max(2 * fh, w + fh - 0.04)
        approach = [
            KinWaypoint(px, py, hth, arm, open_gap),
            KinWaypoint(gx, gy, hth, arm, open_gap, speed=0.5),
            KinWaypoint(gx, gy, hth, arm, close_gap, wait=2),
        ]
        # The final approach does not depend on the route to it: check it once, first.
        pre, grasp = ([wp.x, wp.y, wp.theta, wp.arm, wp.gap] for wp in approach[:2])
        self._check_segment(state, pre, grasp, ())
        first: SkillFailure | None = None
        for spot, turn_first in self._turning_spots(state, q):
            tx, ty = spot
            if turn_first:  # turn where the robot stands, then move facing the bar
                route = [
                    KinWaypoint(q[0], q[1], wrap(hth), br, open_gap),
                    KinWaypoint(tx, ty, wrap(hth), br, open_gap),
                ]
            else:  # move as the robot faces, then turn
                route = [
                    KinWaypoint(tx, ty, q[2], q[3], open_gap),
                    KinWaypoint(tx, ty, wrap(hth), br, open_gap),
                ]
            wps = [*route, KinWaypoint(tx, ty, wrap(hth), arm, open_gap), *approach]
            try:
                self._check_path(state, q, wps[:-2])
            except SkillFailure as e:
                first = first or e
                continue
            return wps
        assert first is not None
        raise first

    def _room_beyond(self, ex: float, ey: float, ux: float, uy: float, br: float) -> float:
        """How far (metres) the base centre may go from ``(ex, ey)`` along the unit direction
        ``(ux, uy)`` and stay inside the room below the middle wall (with a 1 cm margin)."""
        cfg = self.context.config
        lo_x, hi_x = cfg.world_min_x + br + 0.01, cfg.world_max_x - br - 0.01
        lo_y = cfg.world_min_y + br + 0.01
        hi_y = (cfg.world_min_y + cfg.world_max_y) / 2 - cfg.wall_height / 2 - br - 0.01
        room = math.inf
        for e, u, lo, hi in ((ex, ux, lo_x, hi_x), (ey, uy, lo_y, hi_y)):
            if u > 1e-9:
                room = min(room, (hi - e) / u)
            elif u < -1e-9:
                room = min(room, (lo - e) / u)
        return room

    def _turning_spots(
        self, state: ObjectCentricState, q: FloatArray
    ) -> list[tuple[tuple[float, float], bool]]:
        """Where the robot may turn to face the bar, each with whether it turns before moving:
        first the fixed spot (at least 0.55 m from the lower and left walls, moving first),
        then, when that route touches something, the nearest spots of a grid below the middle
        wall (a bounded number: every route costs collision checks, per parameter sample)."""
        cfg = self.context.config
        robot = self.objects[0]
        br = float(state[robot][BASE_RADIUS])
        y_hi = (cfg.world_min_y + cfg.world_max_y) / 2 - cfg.wall_height / 2 - br - 0.02
        safe = (max(float(q[0]), 0.55), max(float(q[1]), 0.55))
        grid = [
            (float(x), float(y))
            for x in np.arange(cfg.world_min_x + br + 0.05, cfg.world_max_x - br - 0.05, 0.15)
            for y in np.arange(cfg.world_min_y + br + 0.05, y_hi, 0.15)
        ]
        grid.sort(key=lambda p: math.hypot(p[0] - q[0], p[1] - q[1]))
        spots = [(safe, False), (safe, True)]
        spots += [(p, turn_first) for p in grid[:TURNING_SPOTS] for turn_first in (False, True)]
        return spots

    def _check_path(
        self, state: ObjectCentricState, q: FloatArray, wps: Sequence[KinWaypoint]
    ) -> None:
        """SkillFailure when the robot, following ``wps`` from ``q``, would touch something:
        turns and arm changes are checked in place, moves along their segment."""
        prev = [float(x) for x in q]
        for wp in wps:
            cur = [wp.x, wp.y, wp.theta, wp.arm, wp.gap]
            if abs(wrap(cur[2] - prev[2])) > 1e-9 or abs(cur[3] - prev[3]) > 1e-9:
                for k in range(1, 9):  # check the turn/extension in place
                    t = k / 8
                    mid = [
                        prev[0],
                        prev[1],
                        prev[2] + wrap(cur[2] - prev[2]) * t,
                        prev[3] + (cur[3] - prev[3]) * t,
                        cur[4],
                    ]
                    hit = self._touches(state, mid, ())
                    if hit is not None:
                        raise SkillFailure(f"GraspHook: turning would touch {hit}")
            else:
                self._check_segment(state, prev, cur, ())
            prev = cur


class PreHookController(_HookController):
    """Turn the held hook upright and lay its short arm over the target.

    Objects: ``(robot, hook, target)``.
    """

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(gap, clearance): the upright bar ends 0.02 + 0.1·gap metres left of the target; the "
        "short arm's lower edge ends 0.03 + 0.1·clearance metres above the target's top."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "held") > 0.5

    def waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        env = self.context
        cfg = env.config
        robot, hook, target = self.objects
        v = state[robot]
        br, al = float(v[BASE_RADIUS]), float(v[ARM_LENGTH])
        q = kin_config(state, robot)
        # Where the hook will be, relative to the base, once the robot faces up.
        rel = _hook_offsets_when_up(state, robot, hook)
        mid = (cfg.world_min_y + cfg.world_max_y) / 2
        y_max = mid - cfg.wall_height / 2 - br - 0.02
        spot = self._turning_spot(state, q, rel)
        wps = [
            KinWaypoint(spot[0], spot[1], q[2], q[3], q[4]),
            KinWaypoint(spot[0], spot[1], UP, q[3], q[4]),
        ]
        tgt = block_corners(state, target)
        tx0, tx1, ty1 = float(tgt[:, 0].min()), float(tgt[:, 0].max()), float(tgt[:, 1].max())
        gap = 0.02 + 0.1 * float(self.params[0])
        clearance = 0.03 + 0.1 * float(self.params[1])
        # rel: (bar right edge dx, short arm lower edge dy, short arm tip dx) at the current arm.
        bar_dx, arm_dy, tip_dx = rel
        x_f = tx0 - gap - bar_dx
        if x_f + tip_dx < 0.5 * (tx0 + tx1) + 0.03:
            raise SkillFailure("PreHook: the short arm cannot cover the target's centre")
        need = ty1 + clearance - arm_dy  # base y needed at the current arm extension
        extra = max(0.0, need - y_max)
        arm = q[3] + extra
        if arm > al + 1e-9:
            raise SkillFailure("PreHook: the target is out of reach")
        y_f = need - extra
        x_a = tx0 - 0.05 - tip_dx  # short arm tip left of the target while rising
        wps += [
            KinWaypoint(x_a, spot[1], UP, q[3], q[4]),
            KinWaypoint(x_a, y_f, UP, arm, q[4]),
            KinWaypoint(x_f, y_f, UP, arm, q[4], speed=0.5, wait=1),
        ]
        if not (cfg.world_min_x + br < min(x_a, x_f) and max(x_a, x_f) < cfg.world_max_x - br):
            raise SkillFailure("PreHook: the base would leave the world")
        return wps

    def _turning_spot(
        self, state: ObjectCentricState, q: FloatArray, rel: tuple[float, float, float]
    ) -> tuple[float, float]:
        """A base position from which the robot can turn to face up without the hook leaving
        the world (lowest first, then nearest)."""
        env = self.context
        cfg = env.config
        robot, hook = self.objects[:2]
        h = state[hook]
        base = state[robot][:2]
        hook_rel = np.asarray(h[:2]) - base
        w, s1, s2 = (state.get(hook, k) for k in ("width", "length_side1", "length_side2"))
        local = lobject_shape(w, s1, s2)
        mid = (cfg.world_min_y + cfg.world_max_y) / 2
        y_hi = mid - cfg.wall_height / 2 - float(state[robot][BASE_RADIUS]) - 0.02
        angles = np.linspace(0.0, 1.0, 13)
        dth = wrap(UP - float(q[2]))
        candidates = [
            (y, abs(x - q[0]), x)
            for y in np.arange(0.5, y_hi, 0.1)
            for x in np.arange(0.4, cfg.world_max_x - 0.3, 0.1)
        ]
        for y, _, x in sorted(candidates):
            ok = True
            for t in angles:
                rot = dth * t
                c, s = math.cos(rot), math.sin(rot)
                hx = x + c * hook_rel[0] - s * hook_rel[1]
                hy = y + s * hook_rel[0] + c * hook_rel[1]
                x0, x1, y0, y1 = bounds(place(local, hx, hy, h[2] + rot))
                if (
                    x0 <= 0.02
                    or x1 >= cfg.world_max_x - 0.02
                    or y0 <= 0.02
                    or (y1 >= cfg.world_max_y - 0.02)
                ):
                    ok = False
                    break
            if ok:
                return float(x), float(y)
        raise SkillFailure("PreHook: nowhere to turn the hook upright")


def _hook_offsets_when_up(
    state: ObjectCentricState, robot: Object, hook: Object
) -> tuple[float, float, float]:
    """With the robot turned to face up (same arm): the upright bar's right edge (dx from the
    base), the short arm's lower edge (dy) and its tip (dx)."""
    r, h = state[robot], state[hook]
    dth = wrap(UP - float(r[2]))
    c, s = math.cos(dth), math.sin(dth)
    rel = np.asarray(h[:2]) - np.asarray(r[:2])
    hx = c * rel[0] - s * rel[1]
    hy = s * rel[0] + c * rel[1]
    w, s1, s2 = (state.get(hook, k) for k in ("width", "length_side1", "length_side2"))
    arm_local = np.array([[-w, -s2], [0.0, -s2], [0.0, 0.0], [-w, 0.0]])
    bar_local = np.array([[-s1, -w], [0.0, -w], [0.0, 0.0], [-s1, 0.0]])
    th = float(h[2]) + dth
    arm = np.asarray(transform(arm_local, hx, hy, th))
    bar = np.asarray(transform(bar_local, hx, hy, th))
    return float(bar[:, 0].max()), float(arm[:, 1].min()), float(arm[:, 0].max())


class HookDownController(_HookController):
    """Drive straight down, dragging the target with the short arm. Objects: ``(robot, hook,
    target)``."""

    def initiable(self, state: ObjectCentricState) -> bool:
        return hook_above(state, self.objects[1], self.objects[2])

    def waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        q = kin_config(state, self.robot)
        y_low = float(state[self.robot][BASE_RADIUS]) + 0.05
        return [KinWaypoint(q[0], y_low, q[2], q[3], q[4], speed=0.6)]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The DynPushPullHook2D planning model (any number of obstructions)."""
    robot_t, hook_t, target_t = ot.KIN_ROBOT, ot.HOOK, ot.TARGET_BLOCK

    HandEmpty = Predicate(
        "HandEmpty",
        (robot_t,),
        lambda s, o: all(s.get(b, "held") < 0.5 for b in s.get_objects(ot.DYNAMIC2D_OBJECT)),
    )
    HoldingHook = Predicate(
        "HoldingHook", (robot_t, hook_t), lambda s, o: s.get(o[1], "held") > 0.5
    )
    HookAbove = Predicate("HookAbove", (hook_t, target_t), lambda s, o: hook_above(s, o[0], o[1]))
    TargetAtGoal = Predicate("TargetAtGoal", (target_t,), lambda s, o: env.goal_reached(s))

    r = Variable("?robot", robot_t)
    h = Variable("?hook", hook_t)
    t = Variable("?target", target_t)
    grasp = LiftedOperator(
        "GraspHook",
        (r, h),
        frozenset({HandEmpty.lift([r])}),
        frozenset({HoldingHook.lift([r, h])}),
        frozenset({HandEmpty.lift([r])}),
    )
    prehook = LiftedOperator(
        "PreHook",
        (r, h, t),
        frozenset({HoldingHook.lift([r, h])}),
        frozenset({HookAbove.lift([h, t])}),
    )
    down = LiftedOperator(
        "HookDown",
        (r, h, t),
        frozenset({HoldingHook.lift([r, h]), HookAbove.lift([h, t])}),
        frozenset({TargetAtGoal.lift([t])}),
        frozenset({HookAbove.lift([h, t])}),
    )

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({TargetAtGoal.ground([o]) for o in state.get_objects(target_t)})

    return PlanningModel(
        name="dynpushpullhook2d",
        env=env,
        types=(robot_t, hook_t, target_t),
        predicates=(HandEmpty, HoldingHook, HookAbove, TargetAtGoal),
        skills=(
            Skill(grasp, GraspHookController, env),
            Skill(prehook, PreHookController, env),
            Skill(down, HookDownController, env),
        ),
        goal_fn=goal,
        max_skill_horizon=250,
    )
