"""DynPushT2D model: the goal predicate, the T geometry and the closed-loop pushing skill."""

from __future__ import annotations

import math

import numpy as np

from kinder_bench.baselines.bilevel_planning import plan_reaches_goal
from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic2d.dyn_pusht2d import PushTController, tee_distance
from kinder_gym.skills import execute_skill


def test_pusht_abstraction_on_hand_built_states() -> None:
    env = make_object_centric("kinder/DynPushT2D-t1-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    tblock, goal = env.tblock, env.goal_tblock  # type: ignore[attr-defined]
    assert {str(a) for a in model.abstract(state)} == {"(NotAtGoal tblock goal_tblock)"}
    for f in ("x", "y"):
        state.set(tblock, f, state.get(goal, f) + 0.02)
    # Angles compare wrapped: 2π + 0.1 rad away is 0.1 rad (< 8°) away.
    state.set(tblock, "theta", state.get(goal, "theta") + 0.1 - 2 * math.pi)
    assert {str(a) for a in model.abstract(state)} == {"(AtGoal tblock goal_tblock)"}
    assert env.goal_reached(state)
    state.set(tblock, "y", state.get(goal, "y") + 0.04)
    assert {str(a) for a in model.abstract(state)} == {"(NotAtGoal tblock goal_tblock)"}
    assert {str(a) for a in model.goal(state)} == {"(AtGoal tblock goal_tblock)"}


def test_tee_distance_matches_the_shape() -> None:
    # T of width 0.1, bar 1.0, stem 1.0 at the origin, unrotated.
    dims = (0.1, 1.0, 1.0)
    pts = np.array([[0.0, -0.05], [0.0, 0.3], [0.6, -0.05], [0.3, -0.5], [0.0, -1.3]])
    d = tee_distance(pts, (0.0, 0.0, 0.0), dims)
    np.testing.assert_allclose(d, [0.0, 0.3, 0.1, 0.25, 0.2], atol=1e-12)
    # Turned by −90°: local +y points along world +x, so the stem hangs towards world −x.
    pts = np.array([[0.3, 0.0], [-0.5, 0.0], [-0.5, 0.2]])
    d = tee_distance(pts, (0.0, 0.0, -math.pi / 2), dims)
    np.testing.assert_allclose(d, [0.3, 0.0, 0.15], atol=1e-12)


def test_pusht_skill_reaches_the_goal() -> None:
    env = make_object_centric("kinder/DynPushT2D-t1-v0")
    model = create_model(env)
    state = env.reset(seed=1)[0]
    (op,) = model.ground_operators(state)
    assert op.name == "PushToGoal(robot, tblock, goal_tblock)"
    gs = model.skill(op)
    assert isinstance(gs.controller, PushTController)
    params = gs.controller.sample_parameters(state, np.random.default_rng(1))
    out = execute_skill(
        gs.controller, state, params, env.transition, model.max_skill_horizon, stop_on_goal=False
    )
    assert out.finished and env.goal_reached(out.states[-1])
    assert model.abstract(out.states[-1]) == op.apply(model.abstract(state))
    assert len(out.actions) <= 1000
    # Every action is within the env's bounds (no clipping hides a bad command).
    assert all(np.all(np.abs(a) <= env.action_space.high + 1e-12) for a in out.actions)


def test_bilevel_planner_solves_pusht() -> None:
    env = make_object_centric("kinder/DynPushT2D-t1-v0")
    solved, _ = plan_reaches_goal(env, seed=3)
    assert solved
