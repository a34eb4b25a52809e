"""The PickPlace3D (MuJoCo) model: predicates on hand-built states, skills, and the planner."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import abstract_atoms, check_planning_model, move_object

ENV_ID = "kinder/PickPlace3D-o1-v0"


@pytest.fixture(scope="module")
def env():
    e = make_object_centric(ENV_ID)
    yield e
    e.close()


def test_predicates_on_hand_built_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    cube, robot = env.objects["cube1"], env.objects["robot"]
    assert abstract_atoms(model, state) == {"(HandEmpty robot)", "(Loose cube1)"}
    assert {str(a) for a in model.goal(state)} == {"(HandEmpty robot)", "(Placed cube1)"}
    # Resting on the floor in the goal region (x 0.95-1.25, y 0.35-0.65): Placed.
    placed = state.copy()
    move_object(placed, cube, (1.1, 0.5, 0.02))
    assert abstract_atoms(model, placed) == {"(HandEmpty robot)", "(Placed cube1)"}
    assert env.goal(placed)
    # Just outside the region: still Loose.
    move_object(placed, cube, (1.3, 0.5, 0.02))
    assert abstract_atoms(model, placed) == {"(HandEmpty robot)", "(Loose cube1)"}
    # A closed hand with the cube lifted at its pinch point holds it; HandEmpty goes away.
    held = state.copy()
    held.set(robot, "pos_gripper", 0.8)
    pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
    move_object(held, cube, pinch - np.array([0.0, 0.0, 0.01]))
    assert abstract_atoms(model, held) == {"(Holding robot cube1)"}
    # Closed on nothing: neither HandEmpty nor Holding.
    fist = state.copy()
    fist.set(robot, "pos_gripper", 0.99)
    assert abstract_atoms(model, fist) == {"(Loose cube1)"}


def test_grounding_and_pddl(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    names = sorted(o.name for o in model.ground_operators(state))
    assert names == ["Pick(robot, cube1)", "Place(robot, cube1)"]
    domain = model.domain_pddl()
    assert "(:action Pick" in domain and "(:action Place" in domain
    assert "(Placed cube1)" in model.problem_pddl(state)


def test_place_is_not_initiable_with_an_open_hand(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Place"))
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(op).controller, state, [0.5, 0.5], env.transition, 10)


@pytest.mark.parametrize("seed", [1001, 1002])
def test_pick_and_place_reach_their_predictions(env, seed: int) -> None:
    model = create_model(env)
    state = env.reset(seed=seed)[0]
    # The Place runs on past the env's goal (which holds while the held cube passes over the
    # region) so that the release and the rise are checked too.
    final = check_planning_model(
        model,
        state,
        ["Pick(robot, cube1)", "Place(robot, cube1)"],
        np.random.default_rng(seed),
        samples=3,
        stop_on_goal=False,
        check_action_bounds=True,
        check_params_space=True,
    )
    cube = env.objects["cube1"]
    assert final.get(cube, "z") == pytest.approx(0.02, abs=3e-3)  # resting on the floor
    assert env.goal_atoms(final) == {"on(cube1, goal_region)": True}


@pytest.mark.slow
def test_planner_solves_an_episode(env) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    reached, stats = plan_reaches_goal(env, 1003, BilevelPlanningArgs(planning_timeout=60))
    assert reached, stats
