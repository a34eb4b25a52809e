"""Kinematic3D models (need the ``[3d]`` extra: kinder-garden3d)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.skills import execute_skill
from kinder_gym.testing import check_planning_model


def test_basemotion3d_predicates_and_skill() -> None:
    env = make_object_centric("kinder/BaseMotion3D-v0")
    model = create_model(env)
    state = env.reset(seed=3)[0]
    assert {str(a) for a in model.abstract(state)} == {"(NotAtTarget robot target)"}
    at = state.copy()
    at.set(env.robot, "pos_base_x", state.get(env.target, "x"))
    at.set(env.robot, "pos_base_y", state.get(env.target, "y"))
    assert {str(a) for a in model.abstract(at)} == {"(AtTarget robot target)"}
    op = model.ground_operators(state)[0]
    gs = model.skill(op)
    out = execute_skill(gs.controller, state, [], env.transition, 100, stop_on_goal=False)
    assert out.finished
    assert model.abstract(out.states[-1]) == op.apply(model.abstract(state))
    high = env.action_space.high
    assert all(np.all(np.abs(a) <= high + 1e-9) for a in out.actions)


def test_transport3d_pick_and_place_reach_their_predictions() -> None:
    env = make_object_centric("kinder/Transport3D-o1-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert {str(a) for a in model.abstract(state)} == {
        "(HandEmpty robot)",
        "(OnFloor box0)",
        "(OnFloor cube0)",
    }
    assert {str(a) for a in model.goal(state)} == {
        "(HandEmpty robot)",
        "(OnTable box0 table)",
        "(OnTable cube0 table)",
    }
    steps = ["Pick(robot, cube0)", "Place(robot, cube0, table)"]
    rng = np.random.default_rng(0)  # sample parameters as the planner would
    state = check_planning_model(
        model,
        state,
        steps,
        rng,
        samples=5,
        max_steps=300,
        retry_mispredictions=True,
        require_finished=False,
    )
    assert "(OnTable cube0 table)" in {str(a) for a in model.abstract(state)}
