"""The DynPushT2D planning model: a closed-loop pushing skill for the T block.

The dot robot (a disc) pushes the T-shaped block until its pose matches the goal T within the
env's tolerances (3 cm in x and y, 8° in angle). Pushing is quasi-static (the env's damping
stops the block as soon as contact ends), so the block's motion under a push is fully determined
by the state, and the env's own pure ``transition`` predicts it exactly.

Concepts:

* ``AtGoal(tblock, goal)`` / ``NotAtGoal``: the env's goal test (position within the position
  tolerance on both axes, wrapped angle difference below the angle tolerance).

Operator: ``PushToGoal(?robot, ?tblock, ?goal)``: pre {NotAtGoal}; add {AtGoal}; delete
{NotAtGoal}. Goal: ``AtGoal(tblock, goal_tblock)``.

Skill (closed loop: the block's pose is observed every step). The skill repeats *strokes* until
the goal holds:

1. **Choose a stroke.** Candidate contacts lie on the T's outline (points on each of its eight
   edges where the disc fits, also in the pocket under the bar); the push direction is the
   edge's inward normal, turned by 0 or ±``spread``. For each candidate, the robot is placed just
   outside the contact and the push is rolled out with the env's ``transition``: every candidate
   for 2 steps, the 8 most promising on for up to ``stroke_steps`` steps (a rollout stops after
   three steps without a new best); the best prefix is kept. The pose error is
   ``|Δposition| + angle_weight·|Δθ|`` (metres). The travel to the stroke's start is a
   breadth-first search on a 5 cm grid around the block inflated by the disc (one grid move is
   exactly one action, since each axis moves up to 0.05 per step). The stroke with the most error
   reduction per step (travel + push) is chosen. The push speed shrinks with the error (0.4 × the
   error per step, between 0.008 and 0.05 m), so the final strokes are fine; when no stroke
   reduces the error, the speed is halved, and at the smallest speed one stroke is chosen with
   the angle weighted 5 × more (a way out of "in place but turned").
2. **Travel** along the grid path, then straight in along the edge normal.
3. **Push.** If the block moved during the travel (a graze), the stroke is chosen again.

Parameters (the sampler draws them uniformly): ``angle_weight`` ∈ [0.6, 1.5] m/rad (lighter
weights let the greedy choice bring the block into place turned, and then get stuck),
``stroke_steps`` ∈ [4, 12] (rounded), ``spread`` ∈ [0.2, 0.6] rad. The skill fails
(:class:`~kinder_gym.skills.SkillFailure`) when no stroke reduces the error even so, or when the
error has not improved for 200 steps.

Upstream has no planning model for DynPushT2D. Limits: the stroke choice is greedy (one stroke of
look-ahead); the travel grid ignores walls beyond the disc's clearance, so a block pushed
against a wall can only be pushed away from it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_gym.concepts import GroundAtom, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import goal_operator, goal_predicates
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import Controller, Skill, SkillFailure

#: Travel grid resolution (metres): one grid move is one action at the env's bound of 0.05.
GRID = 0.05
#: Clearance (metres) kept between the disc and the block while travelling.
TRAVEL_CLEARANCE = 0.03
#: Distance (metres) from the block at which a stroke's straight approach starts.
APPROACH_FAR = 0.1
#: Gap (metres) between the disc and the contact when the push starts.
APPROACH_NEAR = 0.005
#: A stroke is re-chosen when the block moved more than this (metres or radians) during travel.
DISTURBED = 1e-4
MIN_SPEED, MAX_SPEED, SPEED_GAIN = 0.008, 0.05, 0.4
#: When no stroke reduces the error, strokes are chosen once with the angle weighted this much
#: more (turning the block in place costs some position error first).
ESCAPE_WEIGHT = 5.0
#: The skill fails when its best error has not improved for this many steps.
STALL_STEPS = 200
#: Every candidate stroke is first rolled out this many steps; the TOP_K best then up to
#: ``stroke_steps``.
PROBE_STEPS, TOP_K = 2, 8
#: Contacts per edge, by edge (top, right end, right underside, stem right, stem bottom, stem
#: left, left underside, left end).
CONTACTS_PER_EDGE = (5, 1, 1, 3, 1, 3, 1, 1)


def tee_outline(width: float, length_h: float, length_v: float) -> FloatArray:
    """The T's outline in its own frame, clockwise from the bar's top-left corner (8 × 2)."""
    w, h, v = width, length_h / 2, length_v
    return np.array(
        [
            [-h, 0.0],
            [h, 0.0],
            [h, -w],
            [w / 2, -w],
            [w / 2, -w - v],
            [-w / 2, -w - v],
            [-w / 2, -w],
            [-h, -w],
        ]
    )


def tee_distance(
    pts: FloatArray, pose: Sequence[float] | FloatArray, dims: Sequence[float]
) -> FloatArray:
    """Distance (metres) from world points ``pts`` (n × 2) to the T at ``pose`` (0 inside)."""
    x, y, th = (float(v) for v in pose)
    w, lh, lv = dims
    c, s = math.cos(th), math.sin(th)
    d = pts - np.array([x, y])
    lx = c * d[:, 0] + s * d[:, 1]
    ly = -s * d[:, 0] + c * d[:, 1]
    out = np.full(len(pts), np.inf)
    for x0, x1, y0, y1 in ((-lh / 2, lh / 2, -w, 0.0), (-w / 2, w / 2, -w - lv, -w)):
        dx = np.maximum(np.maximum(x0 - lx, 0.0), lx - x1)
        dy = np.maximum(np.maximum(y0 - ly, 0.0), ly - y1)
        out = np.minimum(out, np.hypot(dx, dy))
    return out


def pose_error(
    state: ObjectCentricState, tblock: Object, goal: Object, angle_weight: float
) -> float:
    """``|Δposition| + angle_weight·|Δθ|`` between the block and the goal (metres)."""
    t, g = state[tblock], state[goal]
    dth = (float(t[2] - g[2]) + math.pi) % (2 * math.pi) - math.pi
    return math.hypot(float(t[0] - g[0]), float(t[1] - g[1])) + angle_weight * abs(dth)


def at_goal(
    state: ObjectCentricState, tblock: Object, goal: Object, pos_tol: float, ang_tol: float
) -> bool:
    """The env's goal test."""
    t, g = state[tblock], state[goal]
    dth = (float(t[2] - g[2]) + math.pi) % (2 * math.pi) - math.pi
    return bool(abs(t[0] - g[0]) < pos_tol and abs(t[1] - g[1]) < pos_tol and abs(dth) < ang_tol)


@dataclass
class _Rollout:
    """A candidate stroke being rolled out (see :meth:`PushTController._plan_stroke`)."""

    far: FloatArray
    near: FloatArray
    action: FloatArray
    goal_cell: tuple[int, int]
    travel: int
    sim: ObjectCentricState
    best_err: float
    k: int = 0
    best_k: int = 0
    worse: int = 0
    done: bool = False

    def score(self, err0: float) -> float:
        """Error reduction per step (travel and push); 0 without a reduction."""
        return (err0 - self.best_err) / (self.travel + self.best_k) if self.best_k else 0.0


class PushTController(Controller):
    """Push the T block onto the goal, one chosen stroke at a time (see the module docstring).

    Objects: ``(robot, tblock, goal_tblock)``; context: the env.
    """

    params_space = spaces.Box(
        np.array([0.6, 4.0, 0.2]), np.array([1.5, 12.0, 0.6]), dtype=np.float64
    )
    params_doc = (
        "(angle_weight, stroke_steps, spread): the pose error is |Δposition| + "
        "angle_weight·|Δθ| (metres per radian); a stroke pushes for at most stroke_steps actions "
        "(rounded); pushes are along an edge's inward normal or turned by ±spread radians."
    )

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        env = self.context
        cfg = env.config
        self._pos_tol = float(cfg.goal_position_tolerance)
        self._ang_tol = float(cfg.goal_angle_tolerance)
        self._bounds = (
            float(cfg.world_min_x),
            float(cfg.world_max_x),
            float(cfg.world_min_y),
            float(cfg.world_max_y),
        )
        self._step_max = float(env.action_space.high[0])
        nx = round((self._bounds[1] - self._bounds[0]) / GRID)
        ny = round((self._bounds[3] - self._bounds[2]) / GRID)
        xs = self._bounds[0] + (np.arange(nx) + 0.5) * GRID
        ys = self._bounds[2] + (np.arange(ny) + 0.5) * GRID
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        self._cells = np.stack([gx.ravel(), gy.ravel()], axis=1)
        self._shape = (nx, ny)
        self._queue: list[FloatArray] = []
        self._push_from = 0  # queue index where the push starts
        self._planned_pose: FloatArray | None = None
        self._best_err, self._stalled = math.inf, 0

    # -- helpers -------------------------------------------------------------------------------
    def _tee(self, state: ObjectCentricState) -> tuple[FloatArray, tuple[float, float, float]]:
        t = state[self.objects[1]]
        return t[:3].copy(), (float(t[12]), float(t[13]), float(t[14]))

    def _error(self, state: ObjectCentricState, weight: float) -> float:
        return pose_error(state, self.objects[1], self.objects[2], weight)

    def _free_grid(self, state: ObjectCentricState, radius: float) -> np.ndarray:
        pose, dims = self._tee(state)
        d = tee_distance(self._cells, pose, dims).reshape(self._shape)
        x0, x1, y0, y1 = self._bounds
        c = self._cells.reshape(*self._shape, 2)
        inside = (
            (c[..., 0] >= x0 + radius + 0.005)
            & (c[..., 0] <= x1 - radius - 0.005)
            & (c[..., 1] >= y0 + radius + 0.005)
            & (c[..., 1] <= y1 - radius - 0.005)
        )
        result: np.ndarray = (d > radius + TRAVEL_CLEARANCE) & inside
        return result

    def _cell_of(self, p: FloatArray) -> tuple[int, int]:
        i = int(np.clip((p[0] - self._bounds[0]) // GRID, 0, self._shape[0] - 1))
        j = int(np.clip((p[1] - self._bounds[2]) // GRID, 0, self._shape[1] - 1))
        return i, j

    def _cell_centre(self, ij: tuple[int, int]) -> FloatArray:
        return np.array(
            [self._bounds[0] + (ij[0] + 0.5) * GRID, self._bounds[2] + (ij[1] + 0.5) * GRID]
        )

    def _start_cell(self, p: FloatArray, free: np.ndarray) -> tuple[int, int] | None:
        """A free cell one action from ``p`` (the nearest)."""
        ci, cj = self._cell_of(p)
        best: tuple[float, tuple[int, int]] | None = None
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                i, j = ci + di, cj + dj
                if not (0 <= i < self._shape[0] and 0 <= j < self._shape[1]) or not free[i, j]:
                    continue
                off = self._cell_centre((i, j)) - p
                if np.max(np.abs(off)) > self._step_max:
                    continue
                dist = float(np.hypot(*off))
                if best is None or dist < best[0]:
                    best = (dist, (i, j))
        return None if best is None else best[1]

    @staticmethod
    def _bfs(free: np.ndarray, start: tuple[int, int]) -> np.ndarray:
        """Moves (8-connected) from ``start`` to every free cell (−1: unreachable)."""
        dist = np.full(free.shape, -1, dtype=np.int64)
        dist[start] = 0
        frontier = np.zeros(free.shape, dtype=bool)
        frontier[start] = True
        k = 0
        while frontier.any():
            k += 1
            grown = frontier.copy()
            grown[1:, :] |= frontier[:-1, :]
            grown[:-1, :] |= frontier[1:, :]
            g2 = grown.copy()
            g2[:, 1:] |= grown[:, :-1]
            g2[:, :-1] |= grown[:, 1:]
            frontier = g2 & free & (dist < 0)
            dist[frontier] = k
        return dist

    @staticmethod
    def _path(dist: np.ndarray, goal: tuple[int, int]) -> list[tuple[int, int]]:
        """Cells from the start to ``goal`` down the BFS distances (start excluded)."""
        path = [goal]
        i, j = goal
        while dist[i, j] > 0:
            k = dist[i, j]
            for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)):
                a, b = i + di, j + dj
                if 0 <= a < dist.shape[0] and 0 <= b < dist.shape[1] and dist[a, b] == k - 1:
                    i, j = a, b
                    break
            path.append((i, j))
        path.reverse()
        return path[1:]

    def _moves(self, start: FloatArray, end: FloatArray) -> list[FloatArray]:
        """Equal actions moving straight from ``start`` to ``end`` within the bounds."""
        d = end - start
        n = math.ceil(float(np.max(np.abs(d))) / self._step_max - 1e-9)
        return [d / n] * n if n > 0 else []

    def _candidates(
        self, state: ObjectCentricState, radius: float
    ) -> list[tuple[FloatArray, FloatArray, FloatArray]]:
        """``(far approach point, near start point, push direction)`` in world coordinates."""
        pose, dims = self._tee(state)
        outline = tee_outline(*dims)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        rot = np.array([[c, -s], [s, c]])
        spread = float(self.params[2])
        out = []
        for k, n_pts in enumerate(CONTACTS_PER_EDGE):
            a, b = outline[k], outline[(k + 1) % len(outline)]
            e = (b - a) / np.linalg.norm(b - a)
            normal = rot @ np.array([-e[1], e[0]])
            for f in (np.arange(n_pts) + 0.5) / n_pts:
                contact = rot @ (a + f * (b - a)) + pose[:2]
                near = contact + normal * (radius + APPROACH_NEAR)
                far = contact + normal * (radius + APPROACH_FAR)
                probe = np.stack([near, (near + far) / 2, far])
                if np.any(tee_distance(probe, pose, dims) < radius):
                    continue  # the disc does not fit here (the pocket under the bar)
                for turn in (0.0, spread, -spread):
                    ct, st = math.cos(turn), math.sin(turn)
                    d = -np.array(
                        [ct * normal[0] - st * normal[1], st * normal[0] + ct * normal[1]]
                    )
                    out.append((far, near, d))
        return out

    # -- stroke choice -------------------------------------------------------------------------
    def _extend(self, ro: _Rollout, max_steps: int, weight: float) -> None:
        """Push on (with the env's transition) until ``max_steps`` pushes or three in a row
        without a new best error."""
        while not ro.done and ro.k < max_steps and ro.worse < 3:
            ro.sim, _, goal = self.context.transition(ro.sim, ro.action)
            ro.k += 1
            err = self._error(ro.sim, weight)
            if goal:
                ro.best_k, ro.best_err, ro.done = ro.k, -1.0, True
            elif err < ro.best_err:
                ro.best_k, ro.best_err, ro.worse = ro.k, err, 0
            else:
                ro.worse += 1

    def _plan_stroke(self, state: ObjectCentricState) -> None:
        robot = self.objects[0]
        radius = float(state.get(robot, "radius"))
        p = np.array([state.get(robot, "x"), state.get(robot, "y")])
        free = self._free_grid(state, radius)
        start = self._start_cell(p, free)
        if start is None:
            # Touching the block: back away from it first.
            pose, dims = self._tee(state)
            probe = p + np.array(
                [
                    [GRID, 0.0],
                    [-GRID, 0.0],
                    [0.0, GRID],
                    [0.0, -GRID],
                    [GRID, GRID],
                    [GRID, -GRID],
                    [-GRID, GRID],
                    [-GRID, -GRID],
                ]
            )
            d = tee_distance(probe, pose, dims)
            self._queue = [probe[int(np.argmax(d))] - p]
            self._push_from = len(self._queue)
            self._planned_pose = None
            return
        dist = self._bfs(free, start)
        weight = float(self.params[0])
        err0 = self._error(state, weight)
        max_steps = round(float(self.params[1]))
        speed = float(np.clip(SPEED_GAIN * err0, MIN_SPEED, MAX_SPEED))
        best: tuple[float, list[FloatArray], int] | None = None
        x0, x1, y0, y1 = self._bounds
        while best is None:
            # Stage 1: every reachable candidate pushes PROBE_STEPS steps.
            rollouts: list[_Rollout] = []
            for far, near, direction in self._candidates(state, radius):
                if not (x0 + radius < far[0] < x1 - radius and y0 + radius < far[1] < y1 - radius):
                    continue
                goal_cell = self._cell_of(far)
                if dist[goal_cell] < 0:
                    continue
                centre = self._cell_centre(goal_cell)
                travel = 1 + int(dist[goal_cell]) + len(self._moves(centre, far))
                travel += len(self._moves(far, near))
                sim = state.copy()
                sim.set(robot, "x", float(near[0]))
                sim.set(robot, "y", float(near[1]))
                ro = _Rollout(far, near, direction * speed, goal_cell, travel, sim, err0)
                self._extend(ro, PROBE_STEPS, weight)
                rollouts.append(ro)
            # Stage 2: the most promising ones push on, up to stroke_steps.
            rollouts.sort(key=lambda r: -r.score(err0))
            for ro in rollouts[:TOP_K]:
                self._extend(ro, max_steps, weight)
            for ro in rollouts:
                if ro.best_k == 0:
                    continue
                score = ro.score(err0)
                if best is None or score > best[0]:
                    path = self._path(dist, ro.goal_cell)
                    moves = [self._cell_centre(start) - p]
                    last = self._cell_centre(start)
                    for cell in path:
                        nxt = self._cell_centre(cell)
                        moves.append(nxt - last)
                        last = nxt
                    moves += self._moves(last, ro.far) + self._moves(ro.far, ro.near)
                    moves = [m for m in moves if np.max(np.abs(m)) > 1e-12]
                    best = (score, moves + [ro.action] * ro.best_k, len(moves))
            if best is None:
                if speed > MIN_SPEED / 2:
                    speed /= 2
                elif weight == float(self.params[0]):
                    # Stuck in a local minimum (typically: in place but turned): turn the block
                    # at the cost of its position, then go on with the normal error.
                    weight *= ESCAPE_WEIGHT
                    err0 = self._error(state, weight)
                    speed = MAX_SPEED
                else:
                    raise SkillFailure("DynPushT2D: no stroke reduces the pose error")
        self._queue = best[1]
        self._push_from = best[2]
        self._planned_pose = self._tee(state)[0]

    # -- controller ----------------------------------------------------------------------------
    def step(self) -> FloatArray:
        assert self.state is not None
        err = self._error(self.state, float(self.params[0]))
        if err < self._best_err - 1e-6:
            self._best_err, self._stalled = err, 0
        else:
            self._stalled += 1
            if self._stalled > STALL_STEPS:
                raise SkillFailure(f"DynPushT2D: no progress in {STALL_STEPS} steps")
        if self._queue and self._push_from > 0 and self._planned_pose is not None:
            moved = np.abs(self._tee(self.state)[0] - self._planned_pose)
            if np.max(moved) > DISTURBED:
                self._queue = []  # grazed the block on the way: choose the stroke again
        if not self._queue:
            self._plan_stroke(self.state)
        self._push_from -= 1
        return self._queue.pop(0)

    def terminated(self) -> bool:
        if self.state is None:
            return False
        return at_goal(self.state, self.objects[1], self.objects[2], self._pos_tol, self._ang_tol)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The DynPushT2D planning model."""
    cfg = env.config  # type: ignore[attr-defined]
    pos_tol, ang_tol = float(cfg.goal_position_tolerance), float(cfg.goal_angle_tolerance)
    robot_t, tee_t = ot.DOT_ROBOT, ot.TOBJECT

    def reached(s: ObjectCentricState, o: Sequence[Object]) -> bool:
        return at_goal(s, o[0], o[1], pos_tol, ang_tol)

    AtGoal, NotAtGoal = goal_predicates("AtGoal", (tee_t, tee_t), reached)
    r, t, g = Variable("?robot", robot_t), Variable("?tblock", tee_t), Variable("?goal", tee_t)
    push = goal_operator("PushToGoal", (r, t, g), AtGoal, NotAtGoal, (t, g))
    tblock, goal_obj = env.tblock, env.goal_tblock  # type: ignore[attr-defined]

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        pair = (tblock, goal_obj)
        return frozenset({(AtGoal if reached(state, pair) else NotAtGoal).ground(pair)})

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({AtGoal.ground([tblock, goal_obj])})

    max_steps = env.spec.max_episode_steps if env.spec is not None else None
    return PlanningModel(
        name="dynpusht2d",
        env=env,
        types=(robot_t, tee_t),
        predicates=(AtGoal, NotAtGoal),
        skills=(Skill(push, PushTController, env),),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=max_steps or 1000,
        max_episode_steps=max_steps,
        operator_filter=lambda op, s: op.objects[1:] == (tblock, goal_obj),
    )
