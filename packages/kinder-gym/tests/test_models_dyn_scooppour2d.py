"""DynScoopPour2D model: predicates on edited states, the grasp and scoop-and-pour skills."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_bench.baselines.bilevel_planning import plan_reaches_goal
from kinder_core import ObjectCentricState, make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic2d.dyn_scooppour2d import scoop_tip
from kinder_gym.skills import SkillFailure, execute_skill


def test_scooppour_abstraction_on_edited_states() -> None:
    env = make_object_centric("kinder/DynScoopPour2D-o10-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert {str(a) for a in model.abstract(state)} == {"(HandEmpty robot)"}
    assert {str(a) for a in model.goal(state)} == {"(Poured hook)"}
    state.set(env.hook, "held", 1.0)  # type: ignore[attr-defined]
    assert {str(a) for a in model.abstract(state)} == {"(Holding robot hook)"}
    # Five of the ten objects at rest on the right floor: the env's goal, and Poured.
    for k, obj in enumerate(env.smalls[:5]):  # type: ignore[attr-defined]
        state.set(obj, "x", 2.0 + 0.2 * k)
        state.set(obj, "y", 0.1)
    assert env.goal_reached(state)
    assert "(Poured hook)" in {str(a) for a in model.abstract(state)}
    state.set(env.smalls[0], "vx", 0.1)  # type: ignore[attr-defined]
    assert "(Poured hook)" not in {str(a) for a in model.abstract(state)}


def test_scoop_tip_of_the_initial_scoop() -> None:
    env = make_object_centric("kinder/DynScoopPour2D-o10-v0")
    state = env.reset(seed=0)[0]
    hook = env.hook  # type: ignore[attr-defined]
    x, y = state.get(hook, "x"), state.get(hook, "y")
    # Handle up, foot to the left on the floor (y from the corner up by the width): the tip is
    # 0.5 m left of the corner. Upstream draws the scoop up to 1e-3 rad off upright (the tip then
    # moves by up to 0.5 mm).
    assert abs(state.get(hook, "theta") + np.pi / 2) < 2e-3
    np.testing.assert_allclose(scoop_tip(state, hook), [x - 0.5, y + 0.025], atol=1e-3)


def test_scooppour_skills_reach_their_predictions() -> None:
    env = make_object_centric("kinder/DynScoopPour2D-o10-v0")
    model = create_model(env)
    state = env.reset(seed=4)[0]
    ops = {o.name: o for o in model.ground_operators(state)}
    assert sorted(ops) == ["GraspScoop(robot, hook)", "ScoopAndPour(robot, hook)"]
    op = ops["GraspScoop(robot, hook)"]
    out = execute_skill(
        model.skill(op).controller, state, np.zeros(0), env.transition, 1000, stop_on_goal=False
    )
    atoms = model.abstract(state)
    assert out.finished and model.abstract(out.states[-1]) == op.apply(atoms)
    used = len(out.actions)
    state, atoms = out.states[-1], model.abstract(out.states[-1])
    op = ops["ScoopAndPour(robot, hook)"]
    params = np.array([0.4, 0.03, 1.0, 1.2])
    out = execute_skill(model.skill(op).controller, state, params, env.transition, 1000 - used)
    assert out.finished and env.goal_reached(out.states[-1])
    assert model.abstract(out.states[-1]) == op.apply(atoms)


def test_bilevel_planner_solves_scooppour() -> None:
    env = make_object_centric("kinder/DynScoopPour2D-o10-v0")
    solved, _ = plan_reaches_goal(env, seed=4)
    assert solved


def test_scooppour_fails_when_every_move_is_blocked() -> None:
    """A trip that cannot move (the robot wedged in a pile) ends the skill instead of looping."""
    env = make_object_centric("kinder/DynScoopPour2D-o10-v0")
    model = create_model(env)
    state = env.reset(seed=4)[0]
    state.set(env.hook, "held", 1.0)  # type: ignore[attr-defined]
    ops = {o.name: o for o in model.ground_operators(state)}
    controller = model.skill(ops["ScoopAndPour(robot, hook)"]).controller

    def frozen(s: ObjectCentricState, a: np.ndarray) -> tuple[ObjectCentricState, float, bool]:
        return s, 0.0, False

    with pytest.raises(SkillFailure, match="stuck"):
        execute_skill(controller, state, np.array([0.4, 0.03, 1.0, 1.2]), frozen, 1000)


def test_the_lift_over_the_wall_moves_right_as_it_rises() -> None:
    """The pour's first move rises and moves right at once (a diagonal costs no more actions than
    its longer side), stopping 5 cm short of the wall with the robot and the scoop."""
    from kinder_garden2d.dynamic2d.geometry import bounds, lobject_shape, place
    from kinder_gym.models.dynamic2d.dyn_scooppour2d import CARRY_Y, WALL_MARGIN

    env = make_object_centric("kinder/DynScoopPour2D-o10-v0")
    model = create_model(env)
    state = env.reset(seed=4)[0]
    ops = {o.name: o for o in model.ground_operators(state)}
    grasp = model.skill(ops["GraspScoop(robot, hook)"]).controller
    state = execute_skill(grasp, state, np.zeros(0), env.transition, 1000).states[-1]
    controller = model.skill(ops["ScoopAndPour(robot, hook)"]).controller
    controller.reset(state, np.array([0.4, 0.03, 1.0, 1.2]))
    while controller._phases:  # run the first trip until its pour phase starts
        state = env.transition(state, controller.step())[0]
        controller.observe(state)
    robot, hook = env.robot, env.hook  # type: ignore[attr-defined]
    x0 = state.get(robot, "x")
    target, _, _ = controller._pour(state)[0]
    assert target[1] == CARRY_Y and target[0] > x0 + 0.1
    # At the first move's end the scoop (moved rigidly with the robot) is still left of the wall.
    w, s1, s2 = (state.get(hook, k) for k in ("width", "length_side1", "length_side2"))
    h = state[hook]
    right = bounds(place(lobject_shape(w, s1, s2), h[0] + target[0] - x0, h[1], h[2]))[1]
    cfg = env.config  # type: ignore[attr-defined]
    wall_left = cfg.wall_center_x - cfg.wall_width / 2
    assert right <= wall_left - WALL_MARGIN + 1e-9
