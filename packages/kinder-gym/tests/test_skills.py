"""Controllers, skills and their execution on the toy env."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import (
    PICK,
    PLACE_IN,
    PlaceInController,
    ToyPlaceEnv,
    make_toy_model,
)


def test_each_toy_skill_reaches_its_operators_prediction() -> None:
    env = ToyPlaceEnv()
    x0, _ = env.reset(seed=3)
    model = make_toy_model(env)
    atoms = model.abstract(x0)
    rng = np.random.default_rng(0)
    pick = PICK.ground([env.robot, env.obstruction])
    skill = model.skill(pick)
    out = execute_skill(skill.controller, x0, [], env.transition, 40)
    assert out.finished and len(out.states) == len(out.actions) + 1
    assert model.abstract(out.states[-1]) == pick.apply(atoms)
    # Place the obstruction out of the region (params: 0.1 m).
    place_out = model.ground_operators(x0)
    op = next(o for o in place_out if o.name == "PlaceOut(robot, obstruction, region)")
    out2 = execute_skill(model.skill(op).controller, out.states[-1], [0.1], env.transition, 40)
    assert model.abstract(out2.states[-1]) == op.apply(model.abstract(out.states[-1]))
    # The region sampler proposes positions inside the region.
    ctrl = PlaceInController((env.robot, env.target, env.region), env)
    for _ in range(10):
        (x,) = ctrl.sample_parameters(x0, rng)
        assert 0.85 <= x <= 0.95


def test_a_controller_editing_its_states_cannot_change_the_rollout() -> None:
    env = ToyPlaceEnv()
    x0, _ = env.reset(seed=3)
    model = make_toy_model(env)
    pick = PICK.ground([env.robot, env.obstruction])
    controller = model.skill(pick).controller
    reset, observe = controller.reset, controller.observe

    def scribble(state) -> None:
        state.data[:] += 1.0  # what a careless skill might do to its copy

    def reset_and_scribble(state, params) -> None:
        reset(state, params)
        scribble(state)

    def observe_and_scribble(state) -> None:
        observe(state)
        scribble(state)

    controller.reset = reset_and_scribble  # type: ignore[method-assign]
    controller.observe = observe_and_scribble  # type: ignore[method-assign]
    before = x0.copy()
    out = execute_skill(controller, x0, [], env.transition, 40)
    assert np.array_equal(x0.data, before.data) and out.states[0] is x0
    state = x0
    for action, recorded in zip(out.actions, out.states[1:], strict=True):
        state, _, _ = env.transition(state, action)
        assert np.array_equal(state.data, recorded.data)


def test_infeasible_parameters_raise_skill_failure() -> None:
    env = ToyPlaceEnv()
    x0, _ = env.reset(seed=0)
    model = make_toy_model(env)
    skill = model.skill(PLACE_IN.ground([env.robot, env.target, env.region]))
    # Releasing the target on top of the obstruction is refused by the controller.
    with pytest.raises(SkillFailure, match="overlaps obstruction"):
        execute_skill(skill.controller, x0, [0.9], env.transition, 40)


def test_params_are_validated() -> None:
    env = ToyPlaceEnv()
    x0, _ = env.reset(seed=0)
    ctrl = PlaceInController((env.robot, env.target, env.region), env)
    with pytest.raises(ValueError, match="shape"):
        ctrl.reset(x0, [0.1, 0.2])
    with pytest.raises(ValueError, match="NaN"):
        ctrl.reset(x0, [float("nan")])
    assert "params_space=Box" in ctrl.describe()


def test_model_checks_and_pddl() -> None:
    env = ToyPlaceEnv()
    x0, _ = env.reset(seed=0)
    model = make_toy_model(env)
    assert "(:action PlaceOut" in model.domain_pddl()
    assert "(InRegion target region)" in model.problem_pddl(x0)
    assert [s.name for s in model.skills] == ["Pick", "PlaceIn", "PlaceOut"]
