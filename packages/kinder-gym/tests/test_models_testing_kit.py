"""kinder_gym.testing.check_planning_model on the toy env: a plan it follows, and the misses
it names."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_gym.model import PlanningModel
from kinder_gym.operators import LiftedOperator
from kinder_gym.skills import Skill
from kinder_gym.testing import (
    BLOCK,
    REGION,
    ROBOT,
    HandEmpty,
    Holding,
    InRegion,
    OutOfRegion,
    PickController,
    ToyPlaceEnv,
    check_planning_model,
    make_toy_model,
)


def test_follows_a_plan_to_the_goal() -> None:
    env = ToyPlaceEnv()
    state = env.reset(seed=1000)[0]
    model = make_toy_model(env)
    plan = [
        "Pick(robot, obstruction)",
        "PlaceOut(robot, obstruction, region)",
        "Pick(robot, target)",
        "PlaceIn(robot, target, region)",
    ]
    rng = np.random.default_rng(1000)
    final = check_planning_model(
        model, state, plan, rng, samples=50, stop_on_goal=False, retry_mispredictions=True
    )
    assert env.goal_reached(final)


def test_names_an_unknown_or_inapplicable_step() -> None:
    env = ToyPlaceEnv()
    state = env.reset(seed=1000)[0]
    model = make_toy_model(env)
    rng = np.random.default_rng(1000)
    with pytest.raises(AssertionError, match="no such ground operator"):
        check_planning_model(model, state, ["Fly(robot)"], rng)
    with pytest.raises(AssertionError, match="not applicable"):
        check_planning_model(model, state, ["PlaceIn(robot, target, region)"], rng)


def test_names_a_skill_that_misses_its_prediction() -> None:
    env = ToyPlaceEnv()
    state = env.reset(seed=1000)[0]
    toy = make_toy_model(env)
    # A Pick whose operator forgets that the block ends up held.
    r, b = toy.skills[0].operator.parameters
    wrong = LiftedOperator(
        "Pick",
        (r, b),
        frozenset({HandEmpty.lift([r])}),
        frozenset(),
        frozenset({HandEmpty.lift([r])}),
    )
    model = PlanningModel(
        name="toyplace_wrong",
        env=env,
        types=(ROBOT, BLOCK, REGION),
        predicates=(HandEmpty, Holding, InRegion, OutOfRegion),
        skills=(Skill(wrong, PickController, env),),
        goal_fn=toy.goal,
        max_skill_horizon=40,
    )
    rng = np.random.default_rng(1000)
    with pytest.raises(AssertionError, match=r"Pick\(robot, target\): finished=True"):
        check_planning_model(model, state, ["Pick(robot, target)"], rng)
    with pytest.raises(AssertionError, match="never reached its prediction in 3 samples"):
        check_planning_model(
            model, state, ["Pick(robot, target)"], rng, samples=3, retry_mispredictions=True
        )
