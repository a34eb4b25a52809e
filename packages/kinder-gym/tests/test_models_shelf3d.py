"""The Shelf3D (MuJoCo) model: predicates on hand-built states, skills, and grounding."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinder_gym.testing import abstract_atoms

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.tidybot import (
    Dynamic3DController,
    Segment,
    arm_joints,
    base_pose,
    gripper_quat,
    ik_near,
    pinch_position,
)
from kinder_gym.skills import SkillFailure, execute_skill


@pytest.fixture(scope="module")
def env():
    e = make_object_centric("kinder/Shelf3D-o2-v0")
    yield e
    e.close()


def test_predicates_on_hand_built_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert abstract_atoms(model, state) == {
        "(HandEmpty robot)",
        "(OnGround cube1)",
        "(OnGround cube2)",
    }
    assert {str(a) for a in model.goal(state)} == {
        "(HandEmpty robot)",
        "(OnShelf cube1 cupboard_1)",
        "(OnShelf cube2 cupboard_1)",
    }
    # cube1 resting on shelf 2 (centre 1 cm above the board, inside the goal box).
    frame = env.regions.transform(state, "cupboard_1_goal_region")
    on_shelf = state.copy()
    x, y, z = frame[:3, :3] @ np.array([0.05, 0.0, 0.01]) + frame[:3, 3]
    for feature, value in (("x", x), ("y", y), ("z", z)):
        on_shelf.set(env.objects["cube1"], feature, value)
    assert abstract_atoms(model, on_shelf) == {
        "(HandEmpty robot)",
        "(OnShelf cube1 cupboard_1)",
        "(OnGround cube2)",
    }
    # A closed hand whose pinch point is at cube2 (lifted) holds it; HandEmpty goes away.
    robot = env.objects["robot"]
    held = state.copy()
    held.set(robot, "pos_gripper", 0.85)
    pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
    for feature, value in zip(("x", "y", "z"), pinch - np.array([0.0, 0.0, 0.02]), strict=True):
        held.set(env.objects["cube2"], feature, value)
    assert abstract_atoms(model, held) == {"(Holding robot cube2)", "(OnGround cube1)"}
    # Closed on nothing: neither HandEmpty nor Holding.
    empty_fist = state.copy()
    empty_fist.set(robot, "pos_gripper", 0.99)
    assert abstract_atoms(model, empty_fist) == {"(OnGround cube1)", "(OnGround cube2)"}


def test_grounding_and_pddl(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    names = sorted(o.name for o in model.ground_operators(state))
    assert names == [
        "Pick(robot, cube1)",
        "Pick(robot, cube2)",
        "Place(robot, cube1, cupboard_1)",
        "Place(robot, cube2, cupboard_1)",
    ]
    domain = model.domain_pddl()
    assert "(:action Pick" in domain and "(:action Place" in domain
    problem = model.problem_pddl(state)
    assert "(OnGround cube1)" in problem and "(OnShelf cube2 cupboard_1)" in problem


def test_pick_and_place_reach_their_predictions(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1)[0]
    rng = np.random.default_rng(0)
    ops = {o.name: o for o in model.ground_operators(state)}
    for name in ("Pick(robot, cube1)", "Place(robot, cube1, cupboard_1)"):
        before = model.abstract(state)
        for _ in range(3):  # sample parameters as the planner would
            gs = model.skill(ops[name])
            params = gs.controller.sample_parameters(state, rng)
            assert gs.controller.params_space.contains(params.astype(np.float32))
            try:
                out = execute_skill(gs.controller, state, params, env.transition, 400)
            except SkillFailure:
                continue
            if out.finished and model.abstract(out.states[-1]) == ops[name].apply(before):
                high = env.action_space.high
                assert all(np.all(np.abs(a) <= high + 1e-9) for a in out.actions)
                state = out.states[-1]
                break
        else:
            raise AssertionError(f"{name} never reached its prediction")
    assert "(OnShelf cube1 cupboard_1)" in abstract_atoms(model, state)
    assert env.goal_atoms(state)["on(cube1, cupboard_1_goal_region)"]


def test_place_sampler_draws_free_slots_along_the_shelf(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0].copy()
    # cube2 on the shelf at the first slot (0.22 m along the shelf from its centre).
    frame = env.regions.transform(state, "cupboard_1_goal_region")
    x, y, z = frame[:3, :3] @ np.array([-0.22, 0.0, 0.01]) + frame[:3, 3]
    for feature, value in (("x", x), ("y", y), ("z", z)):
        state.set(env.objects["cube2"], feature, value)
    op = next(
        o for o in model.ground_operators(state) if o.name == "Place(robot, cube1, cupboard_1)"
    )
    controller = model.skill(op).controller
    rng = np.random.default_rng(0)
    drawn = {round(float(controller.sample_parameters(state, rng)[0]), 6) for _ in range(200)}
    assert drawn == {round(k / 7, 6) for k in range(1, 8)}


def test_place_is_not_initiable_with_an_open_hand(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Place"))
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(op).controller, state, [0.5, 0.5], env.transition, 10)


def test_ik_near_reaches_the_pose_and_fails_cleanly_out_of_reach(env) -> None:
    state = env.reset(seed=0)[0]
    robot = env.objects["robot"]
    base = base_pose(state, robot)
    target = base[:2] + 0.5 * np.array([math.cos(base[2]), math.sin(base[2])])
    goal = np.array([*target, 0.2])
    q = ik_near(
        goal, gripper_quat(float(base[2]), math.radians(45)), base, arm_joints(state, robot)
    )
    assert np.allclose(pinch_position(base, q), goal, atol=2e-3)
    with pytest.raises(SkillFailure, match="no IK solution"):
        ik_near(goal + np.array([0.0, 0.0, 3.0]), gripper_quat(0.0, 0.0), base, q)


class _Hold(Dynamic3DController):
    """Closes the hand in place for 3 steps, then tries an unreachable base target."""

    def plan(self, state):
        return [
            Segment(gripper=1.0, arm_tol=1.0, base_tol=1.0, min_steps=3),
            lambda s: [Segment(base=(50.0, 0.0, 0.0), max_steps=2)],
        ]


def test_segment_following_holds_then_fails_on_an_unreached_target(env) -> None:
    state = env.reset(seed=0)[0]
    controller = _Hold((env.objects["robot"],), env)
    controller.reset(state, [])
    actions = []

    def run() -> None:
        nonlocal state
        for _ in range(10):
            actions.append(controller.step())
            state = env.transition(state, actions[-1])[0]
            controller.observe(state)

    with pytest.raises(SkillFailure, match="did not reach its target in 2 steps"):
        run()
    assert len(actions) == 5
    assert all(a[10] == 1.0 and np.allclose(a[:3], 0.0, atol=0.1) for a in actions[:3])
    # Towards (50, 0) at the base speed limit: a 0.1 m step, almost all of it along +x.
    assert math.hypot(actions[3][0], actions[3][1]) == pytest.approx(0.1)
    assert actions[3][0] > 0.09
