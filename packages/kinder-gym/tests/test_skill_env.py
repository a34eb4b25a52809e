"""The skill-level env: grounding checks, step-by-step execution, the Gymnasium env."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_gym.skill_env import (
    InvalidSkillCall,
    SkillCall,
    SkillEnv,
    SkillExecution,
    ground_call,
    run_plan,
)
from kinder_gym.skills import execute_skill
from kinder_gym.testing import ToyPlaceEnv, make_toy_model

PLAN = [
    SkillCall("Pick", ("robot", "obstruction")),
    SkillCall("PlaceOut", ("robot", "obstruction", "region"), (0.62,)),
    SkillCall("Pick", ("robot", "target")),
    SkillCall("PlaceIn", ("robot", "target", "region"), (0.9,)),
]


def _skill_env() -> SkillEnv:
    env = ToyPlaceEnv()
    return SkillEnv(env, make_toy_model(env))


def test_a_plan_of_skill_calls_reaches_the_goal() -> None:
    senv = _skill_env()
    senv.reset(seed=0)
    ok, steps, infos = run_plan(senv, PLAN)
    assert ok
    assert steps == sum(i["steps"] for i in infos) > len(PLAN)
    assert all(i["failure"] is None for i in infos)
    assert infos[0]["finished"]


def test_dict_actions_match_skill_calls() -> None:
    senv = _skill_env()
    obs, _ = senv.reset(seed=3)
    names = [o.name for o in senv.objects]
    skills = [s.name for s in senv.skills]
    assert senv.action_space["params"].shape == (1,)
    assert senv.action_space["objects"].shape == (3,)
    action = {
        "skill": skills.index("Pick"),
        "objects": np.array([names.index("robot"), names.index("obstruction"), 0]),
        "params": np.array([0.5]),  # ignored: Pick has no parameters
    }
    assert senv.to_call(action) == PLAN[0]
    obs1, reward, terminated, truncated, info = senv.step(action)
    assert info["failure"] is None
    assert reward == -info["steps"]
    assert not terminated and not truncated
    assert not obs.allclose(obs1)


def test_an_invalid_call_is_reported_and_takes_no_step() -> None:
    senv = _skill_env()
    obs, _ = senv.reset(seed=0)
    for call, message in [
        (SkillCall("Fly", ("robot",)), "unknown skill 'Fly'"),
        (SkillCall("Pick", ("robot",)), "takes 2 object(s)"),
        (SkillCall("Pick", ("robot", "ghost")), "unknown object 'ghost'"),
        (SkillCall("PlaceIn", ("robot", "region", "region"), (0.9,)), "needs a block"),
        (SkillCall("PlaceIn", ("robot", "target", "region"), ()), "takes 1 continuous"),
    ]:
        obs1, reward, _, _, info = senv.step(call)
        assert message in info["failure"]
        assert info["steps"] == 0 and reward == 0.0
        assert obs1 == obs
    with pytest.raises(InvalidSkillCall, match="skill index"):
        senv.step({"skill": 9, "objects": [0, 0, 0], "params": [0.0]})


def test_a_skill_failure_ends_the_skill_not_the_episode() -> None:
    senv = _skill_env()
    senv.reset(seed=0)
    senv.step(PLAN[0])
    # Releasing the obstruction on top of the target block fails in the controller.
    state = senv.env.get_state()
    target_x = state.get(state.get_object_from_name("target"), "x")
    _, _, terminated, _, info = senv.step(
        SkillCall("PlaceOut", ("robot", "obstruction", "region"), (target_x,))
    )
    assert "SkillFailure" in info["failure"] and not terminated


def test_parameters_are_clipped_to_the_params_space() -> None:
    env = ToyPlaceEnv()
    model = make_toy_model(env)
    x0, _ = env.reset(seed=0)
    _, params = ground_call(model, x0, SkillCall("PlaceIn", ("robot", "target", "region"), (5.0,)))
    assert params.tolist() == [1.2]


def test_execution_replays_execute_skill_action_for_action() -> None:
    env = ToyPlaceEnv()
    model = make_toy_model(env)
    x0, _ = env.reset(seed=1)
    ground, params = ground_call(model, x0, PLAN[0])
    reference = execute_skill(
        model.skill(ground.operator).controller, x0, params, env.transition, 40
    )
    execution = SkillExecution(ground, params, x0, 40)
    state, actions = x0, []
    while not execution.done():
        action = execution.next_action()
        actions.append(action)
        state, _, _ = env.transition(state, action)
        execution.observe(state)
    assert len(actions) == len(reference.actions)
    for a, b in zip(actions, reference.actions):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(RuntimeError, match="after the execution is done"):
        execution.next_action()
