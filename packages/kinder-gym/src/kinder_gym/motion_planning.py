"""Collision-free motion planning in SE(2) and in joint space, with OMPL's RRT-Connect.

Collision checking is pluggable: every planner takes ``is_valid(config) -> bool`` (our own
geometry, never OMPL's). A query

1. rejects an invalid start or goal,
2. returns the straight segment when it is valid (most queries in open scenes),
3. otherwise runs OMPL's RRT-Connect (seeded, so the same query gives the same path) for up to
   ``attempts`` tries, each stopped after ``max_iterations`` or ``timeout`` seconds of the
   current :func:`cap_clock` (wall-clock by default; an attempt cut off by time depends on the
   machine's speed and load),
4. verifies every segment of the result with our own checker at our own resolution
   (``max_step`` per dimension) and shortcuts it with a seeded random shortcutter.

Configurations are numpy vectors; in SE(2) they are ``(x, y, theta)`` with ``theta`` wrapped to
[−π, π) and interpolated the short way round. :func:`interpolate_path` turns a path into waypoints
no further apart than a per-dimension bound (e.g. an env's action bounds), so a controller can
follow it with one action per waypoint.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import time
from collections.abc import Callable, Iterator, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
ValidityFn = Callable[[FloatArray], bool]


_CAP_CLOCK: contextvars.ContextVar[Callable[[], float]] = contextvars.ContextVar(
    "motion_planning_cap_clock", default=time.perf_counter
)


def cap_clock() -> Callable[[], float]:
    """The clock that RRT-Connect attempts' ``timeout`` counts here (``time.perf_counter``
    unless :func:`timeouts_counted_by` set another)."""
    return _CAP_CLOCK.get()


@contextlib.contextmanager
def timeouts_counted_by(clock: Callable[[], float]) -> Iterator[None]:
    """Within the block, RRT-Connect attempts' ``timeout`` counts ``clock``'s seconds (say
    ``time.process_time``: CPU seconds, which a busy machine does not shorten)."""
    token = _CAP_CLOCK.set(clock)
    try:
        yield
    finally:
        _CAP_CLOCK.reset(token)


def params_seed(params: FloatArray, salt: int) -> int:
    """A planner seed that is a function of a skill's parameters (and a salt), so that the same
    sample always plans the same path."""
    return (int(1e6 * float(np.sum(params * np.arange(1, len(params) + 1)))) + salt) % (2**31 - 1)


def wrap_angle(theta: float) -> float:
    """An angle wrapped to [−π, π)."""
    return (theta + math.pi) % (2 * math.pi) - math.pi


def config_delta(a: FloatArray, b: FloatArray, wrap_dims: Sequence[int] = ()) -> FloatArray:
    """``b − a`` with the wrapped dimensions taken the short way round."""
    d = np.asarray(b, dtype=np.float64) - np.asarray(a, dtype=np.float64)
    for i in wrap_dims:
        d[i] = (d[i] + np.pi) % (2 * np.pi) - np.pi
    return d


def num_steps(delta: FloatArray, max_step: FloatArray) -> int:
    """The fewest equal steps that keep every dimension within ``max_step``."""
    return max(1, int(np.ceil(np.max(np.abs(delta) / max_step) - 1e-9)))


def interpolate(
    a: FloatArray, b: FloatArray, max_step: FloatArray, wrap_dims: Sequence[int] = ()
) -> list[FloatArray]:
    """Points from ``a`` (excluded) to ``b`` (included) in equal steps within ``max_step``."""
    d = config_delta(a, b, wrap_dims)
    n = num_steps(d, np.asarray(max_step, dtype=np.float64))
    out = []
    for k in range(1, n + 1):
        p = np.asarray(a, dtype=np.float64) + d * (k / n)
        for i in wrap_dims:
            p[i] = wrap_angle(float(p[i]))
        out.append(p)
    out[-1] = np.array(b, dtype=np.float64)
    for i in wrap_dims:
        out[-1][i] = wrap_angle(float(out[-1][i]))
    return out


def interpolate_path(
    path: Sequence[FloatArray], max_step: ArrayLike, wrap_dims: Sequence[int] = ()
) -> list[FloatArray]:
    """``path`` densified so consecutive points differ by at most ``max_step`` per dimension.

    The first point is kept; duplicate consecutive points are dropped.
    """
    ms = np.asarray(max_step, dtype=np.float64)
    out = [np.asarray(path[0], dtype=np.float64)]
    for q in path[1:]:
        if np.allclose(config_delta(out[-1], q, wrap_dims), 0.0, atol=1e-12):
            continue
        out.extend(interpolate(out[-1], np.asarray(q, dtype=np.float64), ms, wrap_dims))
    return out


def segment_valid(
    a: FloatArray,
    b: FloatArray,
    is_valid: ValidityFn,
    max_step: FloatArray,
    wrap_dims: Sequence[int] = (),
) -> bool:
    """Whether every point on the segment (at ``max_step`` resolution, ``b`` included) is valid."""
    return all(is_valid(p) for p in interpolate(a, b, max_step, wrap_dims))


def path_valid(
    path: Sequence[FloatArray],
    is_valid: ValidityFn,
    max_step: FloatArray,
    wrap_dims: Sequence[int] = (),
) -> bool:
    """Whether the start and every segment of ``path`` are valid."""
    if not is_valid(np.asarray(path[0], dtype=np.float64)):
        return False
    return all(
        segment_valid(path[i], path[i + 1], is_valid, max_step, wrap_dims)
        for i in range(len(path) - 1)
    )


def shortcut_path(
    path: list[FloatArray],
    is_valid: ValidityFn,
    max_step: FloatArray,
    rng: np.random.Generator,
    iterations: int = 50,
    wrap_dims: Sequence[int] = (),
) -> list[FloatArray]:
    """Random shortcutting: replace the stretch between two random vertices by a straight
    segment when it is valid."""
    path = list(path)
    for _ in range(iterations):
        if len(path) <= 2:
            break
        i, j = sorted(rng.choice(len(path), size=2, replace=False).tolist())
        if j - i < 2:
            continue
        if segment_valid(path[i], path[j], is_valid, max_step, wrap_dims):
            path = path[: i + 1] + path[j:]
    return path


@contextlib.contextmanager
def _quiet_ompl() -> Iterator[None]:
    from ompl import util as ou

    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        yield
    finally:
        ou.setLogLevel(level)


def _rrt_connect(
    kind: str,
    start: FloatArray,
    goal: FloatArray,
    is_valid: ValidityFn,
    lower: FloatArray,
    upper: FloatArray,
    resolution: float,
    seed: int,
    timeout: float,
    max_iterations: int,
) -> list[FloatArray] | None:
    """One seeded OMPL RRT-Connect query (``kind`` ``"se2"`` or ``"rn"``)."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    dim = len(start)
    space: ob.StateSpace
    if kind == "se2":
        space = ob.SE2StateSpace()
        bounds = ob.RealVectorBounds(2)
        for i in range(2):
            bounds.setLow(i, float(lower[i]))
            bounds.setHigh(i, float(upper[i]))
        space.setBounds(bounds)

        def to_np(s: object) -> FloatArray:
            return np.array([s.getX(), s.getY(), s.getYaw()])  # type: ignore[attr-defined]

        def to_ompl(q: FloatArray) -> object:
            s = space.allocState()
            s.setX(float(q[0]))
            s.setY(float(q[1]))
            s.setYaw(float(q[2]))
            return s

    else:
        space = ob.RealVectorStateSpace(dim)
        bounds = ob.RealVectorBounds(dim)
        for i in range(dim):
            bounds.setLow(i, float(lower[i]))
            bounds.setHigh(i, float(upper[i]))
        space.setBounds(bounds)

        def to_np(s: object) -> FloatArray:
            return np.array([s[i] for i in range(dim)])  # type: ignore[index]

        def to_ompl(q: FloatArray) -> object:
            s = space.allocState()
            for i in range(dim):
                s[i] = float(q[i])
            return s

    ss = og.SimpleSetup(space)
    ss.setStateValidityChecker(lambda s: bool(is_valid(to_np(s))))
    si = ss.getSpaceInformation()
    extent = max(space.getMaximumExtent(), 1e-9)
    si.setStateValidityCheckingResolution(min(0.5, max(1e-5, resolution / extent)))
    ss.setStartAndGoalStates(to_ompl(start), to_ompl(goal))
    ss.setPlanner(og.RRTConnect(si))
    iterations = [0]
    clock = cap_clock()
    end = clock() + float(timeout)

    def stop() -> bool:  # evaluated by OMPL at every iteration
        iterations[0] += 1
        return iterations[0] > max_iterations or clock() > end

    # OMPL derives every sampler's seed from this global seed: re-seeding per query makes the
    # query deterministic (OMPL logs a harmless complaint, silenced here).
    ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)
    solved = ss.solve(ob.PlannerTerminationCondition(stop))
    if not ss.haveExactSolutionPath() or not bool(solved):
        return None
    path = [to_np(s) for s in ss.getSolutionPath().getStates()]
    path[0] = np.array(start, dtype=np.float64)
    path[-1] = np.array(goal, dtype=np.float64)
    return path


def _plan(
    kind: str,
    start: ArrayLike,
    goal: ArrayLike,
    is_valid: ValidityFn,
    lower: ArrayLike,
    upper: ArrayLike,
    max_step: ArrayLike,
    wrap_dims: Sequence[int],
    seed: int,
    timeout: float,
    max_iterations: int,
    attempts: int,
    shortcut_iterations: int,
) -> list[FloatArray] | None:
    q0 = np.asarray(start, dtype=np.float64).copy()
    q1 = np.asarray(goal, dtype=np.float64).copy()
    for i in wrap_dims:
        q0[i] = wrap_angle(float(q0[i]))
        q1[i] = wrap_angle(float(q1[i]))
    ms = np.asarray(max_step, dtype=np.float64)
    lo = np.asarray(lower, dtype=np.float64)
    hi = np.asarray(upper, dtype=np.float64)
    if not (is_valid(q0) and is_valid(q1)):
        return None
    if segment_valid(q0, q1, is_valid, ms, wrap_dims):
        return [q0, q1]
    # OMPL checks motions at one resolution (a fraction of the space's extent); use the finest
    # of our per-dimension steps so its motions rarely fail our own check below.
    resolution = float(np.min(ms))
    rng = np.random.default_rng(seed)
    with _quiet_ompl():
        for attempt in range(attempts):
            path = _rrt_connect(
                kind,
                q0,
                q1,
                is_valid,
                lo,
                hi,
                resolution,
                seed + attempt,
                timeout,
                max_iterations,
            )
            if path is None:
                continue
            path = shortcut_path(path, is_valid, ms, rng, shortcut_iterations, wrap_dims)
            if path_valid(path, is_valid, ms, wrap_dims):
                return path
    return None


def plan_se2(
    start: ArrayLike,
    goal: ArrayLike,
    is_valid: ValidityFn,
    bounds: tuple[tuple[float, float], tuple[float, float]],
    max_step: ArrayLike = (0.02, 0.02, math.pi / 32),
    seed: int = 0,
    timeout: float = 1.0,
    max_iterations: int = 20_000,
    attempts: int = 2,
    shortcut_iterations: int = 50,
) -> list[FloatArray] | None:
    """A collision-free SE(2) path from ``start`` to ``goal`` (both ``(x, y, theta)``), or None.

    Args:
        start: The start pose (metres, metres, radians).
        goal: The goal pose.
        is_valid: ``is_valid(np.array([x, y, theta]))`` is True where the robot is collision-free.
        bounds: ``((x_min, x_max), (y_min, y_max))`` for sampling, in metres.
        max_step: Collision-checking resolution per dimension (metres, metres, radians).
        seed: Makes the query deterministic.
        timeout: Seconds per RRT-Connect attempt, of :func:`cap_clock` (wall-clock by default).
        max_iterations: RRT-Connect iterations per attempt.
        attempts: RRT-Connect attempts (each with a new seed) before giving up.
        shortcut_iterations: Random shortcut tries on the found path.

    Returns:
        The path's vertices (start first, goal last), or None when no path was found.
    """
    (x0, x1), (y0, y1) = bounds
    return _plan(
        "se2",
        start,
        goal,
        is_valid,
        [x0, y0, -math.pi],
        [x1, y1, math.pi],
        max_step,
        (2,),
        seed,
        timeout,
        max_iterations,
        attempts,
        shortcut_iterations,
    )


def plan_joint_space(
    start: ArrayLike,
    goal: ArrayLike,
    is_valid: ValidityFn,
    lower: ArrayLike,
    upper: ArrayLike,
    max_step: ArrayLike | float = 0.05,
    seed: int = 0,
    timeout: float = 1.0,
    max_iterations: int = 20_000,
    attempts: int = 2,
    shortcut_iterations: int = 50,
) -> list[FloatArray] | None:
    """A collision-free joint-space path (a box of joint limits), or None.

    ``max_step`` is the collision-checking resolution (radians or metres per joint; a scalar
    applies to every joint). Other arguments as :func:`plan_se2`.
    """
    lo = np.asarray(lower, dtype=np.float64)
    ms = np.broadcast_to(np.asarray(max_step, dtype=np.float64), lo.shape)
    return _plan(
        "rn",
        start,
        goal,
        is_valid,
        lo,
        upper,
        ms,
        (),
        seed,
        timeout,
        max_iterations,
        attempts,
        shortcut_iterations,
    )
