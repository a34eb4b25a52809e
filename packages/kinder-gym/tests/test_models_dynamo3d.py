"""The Dynamo3D (MuJoCo) model: predicates on hand-built states, the skill, planning."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_gym.testing import abstract_atoms

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.dynamo3d import MoveToGoalController
from kinder_gym.skills import SkillFailure, execute_skill


@pytest.fixture(scope="module")
def env():
    e = make_object_centric("kinder/Dynamo3D-o3-v0")
    yield e
    e.close()


def test_predicates_on_hand_built_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    assert abstract_atoms(model, state) == {"(HandEmpty robot)"}
    assert {str(a) for a in model.goal(state)} == {"(AtGoal robot)"}
    robot = env.objects["robot"]
    box = env.task.regions["ground_goal_region"].boxes[0]  # o3: (3.45..4.2)^2 as upstream's
    there = state.copy()
    there.set(robot, "pos_base_x", float(box[3]) - 0.05)
    there.set(robot, "pos_base_y", float(box[1]) + 0.05)
    assert abstract_atoms(model, there) == {"(HandEmpty robot)", "(AtGoal robot)"}
    there.set(robot, "pos_base_y", float(box[1]) - 0.05)  # just outside the goal area
    there.set(robot, "pos_gripper", 0.9)
    assert abstract_atoms(model, there) == set()
    assert [o.name for o in model.ground_operators(state)] == ["MoveToGoal(robot)"]


def test_move_to_goal_pushes_the_chair_and_reaches_the_goal(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    chair = env.objects["obstacle_chair_1"]
    start = np.array([state.get(chair, "x"), state.get(chair, "y")])
    assert np.all((start >= 3.15) & (start <= 3.75))  # in its region, across the goal's corner
    op = model.ground_operators(state)[0]
    out = execute_skill(model.skill(op).controller, state, [0.5, 0.5, 0.5], env.transition, 200)
    assert out.terminated and env.goal_reached(out.states[-1])
    assert "(AtGoal robot)" in abstract_atoms(model, out.states[-1])
    end = np.array([out.states[-1].get(chair, "x"), out.states[-1].get(chair, "y")])
    assert np.linalg.norm(end - start) > 0.1  # the chair was shoved out of the way
    high = env.action_space.high
    assert all(np.all(np.abs(a) <= high + 1e-9) for a in out.actions)


def test_closed_hand_is_not_initiable(env) -> None:
    state = env.reset(seed=1000)[0]
    closed = state.copy()
    closed.set(env.objects["robot"], "pos_gripper", 0.9)
    controller = MoveToGoalController((env.objects["robot"],), env)
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(controller, closed, [0.5, 0.5, 0.5], env.transition, 10)


def test_planner_solves_seeded_instances() -> None:
    from kinder_bench.baselines.bilevel_planning import plan_reaches_goal

    for env_id in ("kinder/Dynamo3D-o1-v0", "kinder/Dynamo3D-o12-v0"):
        e = make_object_centric(env_id)
        try:
            solved, _ = plan_reaches_goal(e, 1)
        finally:
            e.close()
        assert solved, env_id
