"""The DynPushPullHook2D planning model: grasp the hook, then rake or sweep the target down.

The hook is an L: a long bar (``length_side1``) from its outer corner along local −x and a short
arm (``length_side2``) along local −y. The robot grasps the long bar at its free end, pointing
along the bar (the fingers close across it), then turns to face up (+y): the long bar then stands
upright above the robot with the short arm at its top pointing right, like a rake. Then either
the rake comes up beside the target (left of it), slides the short arm over the target's top and
drives straight down, dragging the target onto the middle wall; or the upright bar rises just
right of the target and turns leftwards, its left side sweeping the target down onto the wall.

Concepts:

* ``HandEmpty(robot)`` / ``HoldingHook(robot, hook)``: the hook is (not) held.
* ``HookAbove(hook, target)``: the hook is held and its short arm lies over the target (its lower
  edge above the target's top, its x-range covering the target's centre).
* ``TargetAtGoal(target)``: the env's goal test (the target overlaps the middle wall).

Operators: ``GraspHook(?robot, ?hook)`` (pre HandEmpty; add HoldingHook; delete HandEmpty),
``PreHook(?robot, ?hook, ?target)`` (pre HoldingHook; add HookAbove), ``HookDown(?robot, ?hook,
?target)`` (pre HoldingHook, HookAbove; add TargetAtGoal; delete HookAbove), ``SweepTarget(?robot,
?hook, ?target)`` (pre HoldingHook; add TargetAtGoal). Goal: ``TargetAtGoal(target_block)``.

Obstructions are not part of the abstraction: the held hook (infinite mass) pushes them aside.

Skills:

* GraspHook: when the bar's free end lies too near a wall for the robot to stand beyond it (about
  a third of the instances), the closed fingertips first shove the hook along its bar by its
  short arm, then the robot leaves to the lower left. The arm's length is capped so that the
  approach pose, on the bar's axis beyond the free end, keeps the base inside the room below the
  middle wall; when the route to the spot where the robot turns to face the bar touches
  something, it tries other spots (nearest first).
* PreHook and SweepTarget turn the robot upright with the arm retracted, in two parts (the short
  arm hangs below the bar while the robot faces right, so that part needs height; the rest is
  done lower down, where the upright hook passes below a target just above the middle wall), at
  a spot where the turning hook touches neither the walls nor the target.
* PreHook: the rake comes from the target's left, so its short arm needs about 0.6 m of room
  left of the target; a target nearer the left wall is SweepTarget's.
* SweepTarget: turns anticlockwise as far as the hook stays inside the room (at most
  SWEEP_TURN), then drives down with the arm retracting. It cannot serve a target near the right
  wall (no room for the upright bar right of it), which is PreHook's.
* HookDown drives down with the arm retracting, then turns clockwise (the short arm tilts down
  like a rake's tooth) for a target still short of the wall. HookDown and SweepTarget end as
  soon as the target overlaps the wall.

What limits the model (``benchmarks/results/bilevel_planning.md``, "DynPushPullHook2D: where
planning fails" and "shove, sweep, lower rake"): the first planning call now finds a plan in
49 of 50 episodes on o0 and 50 of 50 on o5, and BP solves 0.96 of o5 (5 × 50). What still
fails: a target near the right wall (no room for SweepTarget) whose obstructions the rising rake
shoves into it, out of reach.
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
    KinRobotController,
    KinWaypoint,
    hook_local,
    hook_shape,
    kin_config,
    wrap,
)
from kinder_gym.models.hand import pick_operator, tool_operator
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import Skill, SkillFailure

UP = math.pi / 2
#: Grid spots GraspHook tries for turning to face the bar when the fixed spot does not work.
TURNING_SPOTS = 12
#: When the bar's free end lies too near a wall for the robot to stand beyond it, GraspHook
#: first shoves the hook along its bar until an arm this much (m) longer than the retracted one
#: fits there.
SHOVE_SPARE_ARM = 0.15
#: Where the shoving fingertips press the short arm (m, hook frame: below the bar's top edge)
#: and how far (rad) the robot points above the bar's axis (its base then clears the bar).
SHOVE_CONTACT_Y = -0.25
SHOVE_TILT = 0.3
#: PreHook turns the robot upright in two parts: first to this far (rad) short of upright,
#: then, lower down, the rest.
TURN_SHORT = 0.5
#: SweepTarget turns the upright hook leftwards by at most this much (rad).
SWEEP_TURN = 1.4
#: HookDown ends by turning the robot this far (rad) clockwise at the bottom.
HOOK_DOWN_SWEEP = 0.6


def block_shape(state: ObjectCentricState, block: Object) -> WorldShape:
    """A rectangle block in the world."""
    f = state[block]
    return place(rect_shape(state.get(block, "width"), state.get(block, "height")), *f[:3])


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
                other = block_shape(state, o)
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

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        self._shoving = False
        super().reset(state, params)

    def step(self) -> FloatArray:
        assert self.state is not None
        if self._shoving and super().terminated():
            # The shove is done: plan the grasp from where the hook came to rest.
            self._shoving = False
            self._follow(self.waypoints(self.state))
        return super().step()

    def terminated(self) -> bool:
        return not self._shoving and super().terminated()

    def waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        if self._longest_arm(state) >= float(state[self.robot][BASE_RADIUS]):
            return self._grasp_waypoints(state)
        self._shoving = True
        return self._shove_waypoints(state)

    def _longest_arm(self, state: ObjectCentricState) -> float:
        """The longest arm with which the approach pose, on the bar's axis beyond its free end,
        keeps the base inside the room (below the base radius: no room at all)."""
        robot, hook = self.objects
        v = state[robot]
        br, al = float(v[BASE_RADIUS]), float(v[ARM_LENGTH])
        fw = float(v[FINGER_WIDTH])  # the fingers start at the gripper base's centre
        hx, hy, hth = (float(c) for c in state[hook][:3])
        w, s1 = state.get(hook, "width"), state.get(hook, "length_side1")
        c, s = math.cos(hth), math.sin(hth)
        end_x, end_y = hx - c * s1 + s * w / 2, hy - s * s1 - c * w / 2
        return min(al, self._room_beyond(end_x, end_y, -c, -s, br) - 0.06 - fw)

    def _shove_waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        """Push the hook along its bar, away from the wall beyond its free end, until an arm
        SHOVE_SPARE_ARM longer than the retracted one fits there, then leave to the lower left.
        The closed fingertips press the short arm's left face below the bar, the robot pointing
        SHOVE_TILT above the bar's axis so that its base stays clear of the bar (the push turns
        the hook a little)."""
        robot, hook = self.objects
        v = state[robot]
        br, al = float(v[BASE_RADIUS]), float(v[ARM_LENGTH])
        fw, fh = float(v[FINGER_WIDTH]), float(v[FINGER_HEIGHT])
        cfg = self.context.config
        hx, hy, hth = (float(c) for c in state[hook][:3])
        w, s1 = state.get(hook, "width"), state.get(hook, "length_side1")
        c, s = math.cos(hth), math.sin(hth)
        if c < 0.5:
            raise SkillFailure("GraspHook: the bar's free end does not point to the left wall")

        def world(local: FloatArray) -> tuple[float, float]:
            return hx + c * local[0] - s * local[1], hy + s * local[0] + c * local[1]

        # Moving the hook along its bar moves the free end along the approach axis.
        push = br + SHOVE_SPARE_ARM - self._longest_arm(state)
        reach = al + fw  # the fingers start at the gripper base's centre
        tip = np.array([-w - 0.005, SHOVE_CONTACT_Y])
        tilt = np.array([math.cos(SHOVE_TILT), math.sin(SHOVE_TILT)])
        contact = tip - reach * tilt  # the base when the fingertips touch the short arm
        along = np.array([1.0, 0.0])
        pre, done = contact - 0.1 * along, contact + push * along
        back = done - 0.15 * along
        th = wrap(hth + SHOVE_TILT)
        gap = 2 * fh
        q = kin_config(state, robot)
        low_y = cfg.world_min_y + br + 0.06
        px, py = world(pre)

        def approach(x: float, y: float, heading: float) -> list[KinWaypoint]:
            return [
                KinWaypoint(x, y, q[2], br, gap),  # retract and close before turning
                KinWaypoint(x, y, heading, br, gap),
                KinWaypoint(px, py, heading, br, gap),
                KinWaypoint(px, py, th, br, gap),
                KinWaypoint(px, py, th, al, gap),
            ]

        # Where the robot starts with its fingers by the bar, it first backs off to the lower
        # left as it stands (open fingers may fit there where closing ones do not); it drives
        # to the start of the push facing along the bar or already tilted (the fingertips
        # then reach higher, nearer the bar).
        away = (max(cfg.world_min_x + br + 0.02, q[0] - 0.1), cfg.world_min_y + br + 0.02)
        routes = [
            ([], approach(q[0], q[1], th)),
            ([], approach(q[0], q[1], hth)),
            ([KinWaypoint(*away, *q[2:])], approach(*away, th)),
            ([KinWaypoint(*away, *q[2:])], approach(*away, hth)),
        ]
        first_failure: SkillFailure | None = None
        for lead, route in routes:
            try:
                self._check_path(state, q, [*lead, *route])
            except SkillFailure as e:
                first_failure = first_failure or e
                continue
            wps = [*lead, *route]
            break
        else:
            assert first_failure is not None
            raise first_failure
        end_x = hx - c * (s1 - push) + s * w / 2  # where the free end will be
        leave_x = max(cfg.world_min_x + br + 0.05, end_x - 0.5)
        return [
            *wps,
            KinWaypoint(*world(done), th, al, gap, speed=0.5),
            KinWaypoint(*world(back), th, al, gap),
            KinWaypoint(*world(back), th, br, gap),
            KinWaypoint(world(back)[0], low_y, th, br, gap),
            KinWaypoint(leave_x, low_y, th, br, gap),
        ]

    def _grasp_waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        robot, hook = self.objects
        v = state[robot]
        br = float(v[BASE_RADIUS])
        fw, fh = float(v[FINGER_WIDTH]), float(v[FINGER_HEIGHT])
        open_gap = float(v[GRIPPER_BASE_HEIGHT])
        # The fingertips pass the bar's free end by this much: the end then lies 0.04-0.09 m
        # from the gripper base's centre, on the fingers' first half (where a grasp needs a
        # contact) and clear of the gripper base (0.03 m half-width).
        overlap = 0.11 + 0.05 * float(self.params[0])
        hx, hy, hth = (float(c) for c in state[hook][:3])
        w, s1 = state.get(hook, "width"), state.get(hook, "length_side1")
        c, s = math.cos(hth), math.sin(hth)

        def world(lx: float, ly: float) -> tuple[float, float]:
            return hx + c * lx - s * ly, hy + s * lx + c * ly

        # The approach comes along the bar's axis from beyond its free end: near a wall only a
        # shorter arm leaves the base room there.
        longest = self._longest_arm(state)
        if longest < br:
            raise SkillFailure("GraspHook: no room for the robot beyond the bar's free end")
        arm = br + float(self.params[1]) * (longest - br)
        reach = arm + fw  # the fingertips, from the base
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


class _StopAtGoal(KinRobotController):
    """Ends as soon as the target overlaps the middle wall (going on could push it past)."""

    def terminated(self) -> bool:
        return super().terminated() or (
            self.state is not None and bool(self.context.goal_reached(self.state))
        )


def _first_turn(q: FloatArray) -> float:
    """The first part (rad) of the turn from ``q``'s heading to upright: TURN_SHORT short of
    it (none when the turn is shorter than that)."""
    dth = wrap(UP - float(q[2]))
    return wrap(dth - math.copysign(TURN_SHORT, dth)) if abs(dth) > TURN_SHORT else 0.0


class _UprightController(_HookController):
    """Skills that start by turning the held hook upright. Objects: ``(robot, hook, target)``."""

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "held") > 0.5

    def _turn_upright(self, state: ObjectCentricState, x_near: float) -> list[KinWaypoint]:
        """Waypoints that retract the arm, turn the robot upright (see :meth:`_turning_spot`)
        and bring it below ``x_near``."""
        q = kin_config(state, self.robot)
        br = float(state[self.robot][BASE_RADIUS])
        x_t, y_turn, y_up = self._turning_spot(state, q, x_near)
        th_short = q[2] + _first_turn(q)
        return [
            KinWaypoint(x_t, y_turn, q[2], q[3], q[4]),
            KinWaypoint(x_t, y_turn, q[2], br, q[4]),
            KinWaypoint(x_t, y_turn, wrap(th_short), br, q[4]),
            KinWaypoint(x_t, y_up, wrap(th_short), br, q[4]),
            KinWaypoint(x_t, y_up, UP, br, q[4]),
            KinWaypoint(x_near, y_up, UP, br, q[4]),
        ]

    def _turning_spot(
        self, state: ObjectCentricState, q: FloatArray, x_near: float
    ) -> tuple[float, float, float]:
        """Where the robot, its arm retracted, turns to face up: ``(x, y_turn, y_up)``. It turns
        at ``(x, y_turn)`` to TURN_SHORT short of upright (facing right, the short arm hangs
        below the bar: it needs room above the lower wall), lowers itself to ``y_up``, turns
        upright there and moves sideways to ``x_near``. The hook stays inside the world and
        touches the target neither while turning nor while moving. Lowest ``y_up`` first, then
        nearest ``x_near``, then lowest ``y_turn``."""
        env = self.context
        cfg = env.config
        robot, hook, target = self.objects
        h = state[hook]
        base = state[robot][:2]
        br = float(state[robot][BASE_RADIUS])
        drop = float(q[3]) - br  # retracting pulls the hook this far back along the heading
        heading = np.array([math.cos(q[2]), math.sin(q[2])])
        hook_rel = np.asarray(h[:2]) - base - drop * heading
        local = hook_local(state, hook)
        tgt = block_shape(state, target)
        mid = (cfg.world_min_y + cfg.world_max_y) / 2
        y_hi = mid - cfg.wall_height / 2 - br - 0.02
        dth = wrap(UP - float(q[2]))
        short = _first_turn(q)

        def hook_at(x: float, y: float, rot: float) -> WorldShape:
            c, s = math.cos(rot), math.sin(rot)
            hx = x + c * hook_rel[0] - s * hook_rel[1]
            hy = y + s * hook_rel[0] + c * hook_rel[1]
            return place(local, hx, hy, h[2] + rot)

        def sweep_fits(x: float, y: float, rot0: float, rot1: float) -> bool:
            for t in np.linspace(0.0, 1.0, 7):
                shape = hook_at(x, y, rot0 + (rot1 - rot0) * t)
                x0, x1, y0, y1 = bounds(shape)
                if (
                    x0 <= 0.02
                    or x1 >= cfg.world_max_x - 0.02
                    or y0 <= 0.02
                    or y1 >= cfg.world_max_y - 0.02
                    or overlaps(shape, tgt)
                ):
                    return False
            return True

        def slide_fits(x: float, y: float) -> bool:
            n = max(1, math.ceil(abs(x_near - x) / 0.05))
            return not any(
                overlaps(hook_at(x + (x_near - x) * k / n, y, dth), tgt) for k in range(n + 1)
            )

        ys = [float(y) for y in np.arange(cfg.world_min_y + br + 0.04, y_hi, 0.1)]
        xs = sorted(
            (float(x) for x in np.arange(0.4, cfg.world_max_x - 0.3, 0.1)),
            key=lambda x: (abs(x - x_near), x),
        )
        first: dict[tuple[float, float], bool] = {}
        for y_up in ys:
            for x in xs:
                if not (sweep_fits(x, y_up, short, dth) and slide_fits(x, y_up)):
                    continue
                for y_turn in ys:
                    if y_turn < y_up:
                        continue
                    if (x, y_turn) not in first:
                        first[x, y_turn] = sweep_fits(x, y_turn, 0.0, short)
                    if first[x, y_turn]:
                        return x, y_turn, y_up
        raise SkillFailure("PreHook: nowhere to turn the hook upright")


class PreHookController(_UprightController):
    """Turn the held hook upright and lay its short arm over the target.

    Objects: ``(robot, hook, target)``.
    """

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(gap, clearance): the upright bar ends 0.02 + 0.1·gap metres left of the target; the "
        "short arm's lower edge ends 0.03 + 0.1·clearance metres above the target's top."
    )

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
        tgt = block_corners(state, target)
        tx0, tx1, ty1 = float(tgt[:, 0].min()), float(tgt[:, 0].max()), float(tgt[:, 1].max())
        gap = 0.02 + 0.1 * float(self.params[0])
        clearance = 0.03 + 0.1 * float(self.params[1])
        # rel: (bar right edge dx, short arm lower edge dy, short arm tip dx) at the current arm;
        # the arm retracts before the robot turns upright (the rake is then lowest, and sweeps
        # least while turning: a target just above the middle wall stays clear of it).
        bar_dx, arm_dy, tip_dx = rel
        arm_dy -= q[3] - br
        x_f = tx0 - gap - bar_dx
        if x_f + tip_dx < 0.5 * (tx0 + tx1) + 0.03:
            raise SkillFailure("PreHook: the short arm cannot cover the target's centre")
        need = ty1 + clearance - arm_dy  # base y needed with the arm retracted
        extra = max(0.0, need - y_max)
        arm = br + extra
        if arm > al + 1e-9:
            raise SkillFailure("PreHook: the target is out of reach")
        y_f = need - extra
        x_a = tx0 - 0.05 - tip_dx  # short arm tip left of the target while rising
        if not (cfg.world_min_x + br < min(x_a, x_f) and max(x_a, x_f) < cfg.world_max_x - br):
            raise SkillFailure("PreHook: the base would leave the world")
        # Turn upright as near below x_a as the hook allows: the rake then rises beside the
        # target rather than sweeping across it.
        wps = self._turn_upright(state, x_a)
        return [
            *wps,
            KinWaypoint(x_a, y_f, UP, arm, q[4]),
            KinWaypoint(x_f, y_f, UP, arm, q[4], speed=0.5, wait=1),
        ]


class SweepTargetController(_StopAtGoal, _UprightController):
    """Sweep the target down onto the middle wall with the upright bar, turning leftwards.

    Objects: ``(robot, hook, target)``. The robot turns the hook upright, rises with the bar
    just right of the target to the top of its half, turns anticlockwise (the bar's left side
    pushes the target down and to the left) as far as the hook stays inside the room, and
    drives down with the arm retracting, pressing the target onto the middle wall.
    """

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(gap, arm): the upright bar rises 0.03 + 0.12·gap metres right of the target; the arm "
        "is extended by arm·0.12 metres (less where the hook would touch the top wall)."
    )

    def waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        cfg = self.context.config
        robot, hook, target = self.objects
        br = float(state[robot][BASE_RADIUS])
        q = kin_config(state, robot)
        tgt = block_corners(state, target)
        bar_dx = _hook_offsets_when_up(state, robot, hook)[0]
        w = state.get(hook, "width")
        x_s = float(tgt[:, 0].max()) + 0.03 + 0.12 * float(self.params[0]) + w - bar_dx
        if not (
            cfg.world_min_x + br < x_s < cfg.world_max_x - br
            and self._hook_inside(state, (x_s, br + 0.05, UP, br))
        ):
            raise SkillFailure("SweepTarget: no room for the hook right of the target")
        y_top = (cfg.world_min_y + cfg.world_max_y) / 2 - cfg.wall_height / 2 - br - 0.02
        wps = self._turn_upright(state, x_s)
        arm = br + 0.12 * float(self.params[1])
        while arm > br and not self._hook_inside(state, (x_s, y_top, UP, arm)):
            arm = max(br, arm - 0.02)
        turn = 0.0
        while turn < SWEEP_TURN and self._hook_inside(state, (x_s, y_top, UP + turn + 0.05, arm)):
            turn += 0.05
        if turn < 0.3:
            raise SkillFailure("SweepTarget: no room to turn the hook leftwards")
        return [
            *wps,
            KinWaypoint(x_s, y_top, UP, arm, q[4]),
            KinWaypoint(x_s, y_top, UP + turn, arm, q[4], speed=0.5),
            KinWaypoint(x_s, br + 0.05, UP + turn, br, q[4], speed=0.5),
        ]

    def _hook_inside(
        self, state: ObjectCentricState, pose: tuple[float, float, float, float]
    ) -> bool:
        """Whether the held hook stays 4 cm inside the world with the robot at ``pose``
        ``(x, y, theta, arm)`` (the hook moves rigidly with the gripper)."""
        cfg = self.context.config
        robot, hook = self.objects[:2]
        q = kin_config(state, robot)
        x, y, th, arm = pose
        d = th - float(q[2])
        c, s = math.cos(d), math.sin(d)
        grip = np.array([q[0] + q[3] * math.cos(q[2]), q[1] + q[3] * math.sin(q[2])])
        rel = np.asarray(state[hook][:2]) - grip
        hx = x + arm * math.cos(th) + c * rel[0] - s * rel[1]
        hy = y + arm * math.sin(th) + s * rel[0] + c * rel[1]
        x0, x1, y0, y1 = bounds(place(hook_local(state, hook), hx, hy, state[hook][2] + d))
        return bool(
            x0 > cfg.world_min_x + 0.04
            and x1 < cfg.world_max_x - 0.04
            and y0 > cfg.world_min_y + 0.04
            and y1 < cfg.world_max_y - 0.04
        )


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


class HookDownController(_StopAtGoal, _HookController):
    """Drive straight down, dragging the target with the short arm. Objects: ``(robot, hook,
    target)``."""

    def initiable(self, state: ObjectCentricState) -> bool:
        return hook_above(state, self.objects[1], self.objects[2])

    def waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        q = kin_config(state, self.robot)
        br = float(state[self.robot][BASE_RADIUS])
        y_low = br + 0.05
        # Down with the arm retracting, then turn clockwise: the short arm tilts down like a
        # rake's tooth and presses a target still short of the wall onto it.
        return [
            KinWaypoint(q[0], y_low, q[2], br, q[4], speed=0.6),
            KinWaypoint(q[0], y_low, q[2] - HOOK_DOWN_SWEEP, br, q[4], speed=0.5),
        ]


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

    h = Variable("?hook", hook_t)
    t = Variable("?target", target_t)
    grasp = pick_operator("GraspHook", HandEmpty, HoldingHook, h, [])
    above, at_goal = [HookAbove.lift([h, t])], [TargetAtGoal.lift([t])]
    prehook = tool_operator("PreHook", HoldingHook, h, [t], [], above)
    down = tool_operator("HookDown", HoldingHook, h, [t], above, at_goal, above)

    sweep = tool_operator("SweepTarget", HoldingHook, h, [t], [], at_goal)

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
            Skill(sweep, SweepTargetController, env),
        ),
        goal_fn=goal,
        max_skill_horizon=250,
    )
