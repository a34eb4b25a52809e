"""The Obstruction2D planning model: predicates, grounding, skills and planning."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from kinder_core import ObjectCentricState, make_object_centric
from kinder_garden2d.kinematic2d.predicates import is_on
from kinder_gym.concepts import sorted_atoms
from kinder_gym.model import PlanningModel
from kinder_gym.models import create_model
from kinder_gym.models.kinematic2d.obstruction2d import (
    CLEAR_MARGIN,
    PickController,
    PlaceOnTableController,
    is_clear,
)
from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import check_planning_model


def _run(model: PlanningModel, state: ObjectCentricState, name: str, seed: int = 0) -> Any:
    """Run the named ground skill with sampled parameters; check it reaches its prediction."""
    rng = np.random.default_rng(seed)
    return check_planning_model(model, state, [name], rng, stop_on_goal=False)


def test_predicates_on_hand_built_states() -> None:
    env = make_object_centric("kinder/Obstruction2D-o2-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    surface, target = env.target_surface, env.target_block
    o0, o1 = env.obstructions
    sx = state.get(surface, "x")
    # obstruction0 entirely on the surface, obstruction1 far to its right, target to its left.
    state.set(o0, "width", 0.05)
    state.set(o0, "x", sx + 0.01)
    state.set(o1, "x", sx + state.get(surface, "width") + CLEAR_MARGIN + 0.3)
    state.set(target, "x", sx - 0.5 if sx > 0.6 else sx + 0.6)
    assert is_on(state, o0, surface)
    assert sorted_atoms(model.abstract(state)) == [
        "(Clear obstruction1)",
        "(HandEmpty robot)",
        "(OnTable obstruction1)",
        "(OnTable target_block)",
        "(OnTarget obstruction0)",
    ]
    # Just touching the margin around the surface is not clear.
    state.set(o1, "x", sx + state.get(surface, "width") + 0.5 * CLEAR_MARGIN)
    assert not is_clear(state, o1, surface)
    # The robot at a grasp pose over the target with the vacuum on holds it.
    pick = PickController((env.robot, target), env)
    goal = pick.goal_config(state, np.array([0.5]))
    assert goal is not None
    for k, v in zip(("x", "y", "theta", "arm_joint", "vacuum"), [*goal, 1.0]):
        state.set(env.robot, k, float(v))
    atoms = sorted_atoms(model.abstract(state))
    assert "(Holding robot target_block)" in atoms
    assert "(HandEmpty robot)" not in atoms
    assert "(OnTable target_block)" not in atoms
    assert sorted_atoms(model.goal(state)) == ["(OnTarget target_block)"]


def test_grounding() -> None:
    env = make_object_centric("kinder/Obstruction2D-o3-v0")
    model = create_model(env)
    state = env.reset(seed=1)[0]
    names = [o.name for o in model.ground_operators(state)]
    assert not any("target_surface" in n for n in names)
    assert [n for n in names if n.startswith("PlaceOnTarget")] == [
        "PlaceOnTarget(robot, target_block, obstruction0, obstruction1, obstruction2)"
    ]
    assert sorted(n for n in names if n.startswith("PlaceOnTable")) == [
        f"PlaceOnTable(robot, obstruction{i})" for i in range(3)
    ]
    # Picks of every block, from the table and from the target.
    assert sum(n.startswith("Pick") for n in names) == 2 * 4
    assert "(:action PlaceOnTarget" in model.domain_pddl()


def test_skills_reach_their_predictions() -> None:
    env = make_object_centric("kinder/Obstruction2D-o2-v0")
    model = create_model(env)
    state = env.reset(seed=1028)[0]
    atoms = sorted_atoms(model.abstract(state))
    # This seed has obstruction0 on the surface and obstruction1 overlapping it.
    assert "(OnTarget obstruction0)" in atoms and "(Clear obstruction1)" not in atoms
    state = _run(model, state, "PickFromTable(robot, obstruction1)")
    state = _run(model, state, "PlaceOnTable(robot, obstruction1)")
    state = _run(model, state, "PickFromTarget(robot, obstruction0)")
    state = _run(model, state, "PlaceOnTable(robot, obstruction0)")
    state = _run(model, state, "PickFromTable(robot, target_block)")
    name = "PlaceOnTarget(robot, target_block, obstruction0, obstruction1)"
    final = _run(model, state, name)
    assert env.goal_reached(final)


def test_place_on_target_fails_while_blocked() -> None:
    env = make_object_centric("kinder/Obstruction2D-o1-v0")
    model = create_model(env)
    state = env.reset(seed=1012)[0]
    # The obstruction lies on the surface and the target block is too wide to fit beside it.
    assert "(OnTarget obstruction0)" in sorted_atoms(model.abstract(state))
    state = _run(model, state, "PickFromTable(robot, target_block)")
    op = next(o for o in model.ground_operators(state) if o.name.startswith("PlaceOnTarget"))
    assert not op.applicable(model.abstract(state))  # the abstraction knows it is blocked
    gs = model.skill(op)
    for u in np.linspace(0.0, 1.0, 5):
        with pytest.raises(SkillFailure, match="in collision"):
            execute_skill(gs.controller, state, [u], env.transition, 200)


def test_place_on_table_uses_free_table() -> None:
    env = make_object_centric("kinder/Obstruction2D-o4-v0")
    state = env.reset(seed=2)[0]
    ctrl = PlaceOnTableController((env.robot, env.obstructions[0]), env)
    free = ctrl.free_intervals(state)
    assert free
    w = state.get(env.obstructions[0], "width")
    others = [env.target_block, env.target_surface, *env.obstructions[1:]]
    for u in np.linspace(0.0, 1.0, 21):
        x = ctrl.block_x(state, float(u))
        assert x is not None
        for o in others:
            ox, ow = state.get(o, "x"), state.get(o, "width")
            assert x + w < ox or x > ox + ow, (u, o)


@pytest.mark.parametrize(("env_id", "seeds"), [("kinder/Obstruction2D-o2-v0", (0, 1, 2))])
def test_planner_solves_seeded_instances(env_id: str, seeds: tuple[int, ...]) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    env = make_object_centric(env_id)
    for seed in seeds:
        reached, stats = plan_reaches_goal(env, seed, BilevelPlanningArgs(planning_timeout=30))
        assert reached, (env_id, seed, stats)


@pytest.mark.slow
def test_planner_solves_many_o4_instances() -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    env = make_object_centric("kinder/Obstruction2D-o4-v0")
    solved = 0
    for seed in range(20):
        solved += plan_reaches_goal(env, seed, BilevelPlanningArgs(planning_timeout=30))[0]
    assert solved >= 18
