"""The FrankaPickPlace3D (MuJoCo, FR3 arm) model: predicates, IK, skills, and the planner."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.franka_pick_place3d import (
    FrankaController,
    Move,
    arm_joints,
    down_quat,
    pinch_frame,
    solve_ik,
)
from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import abstract_atoms, check_planning_model, move_object

ENV_ID = "kinder/FrankaPickPlace3D-o1-v0"


@pytest.fixture(scope="module")
def env():
    e = make_object_centric(ENV_ID)
    yield e
    e.close()


def test_predicates_on_hand_built_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    cube, robot, desk = env.objects["cube1"], env.objects["robot"], env.objects["desk_1"]
    assert abstract_atoms(model, state) == {"(HandEmpty robot)", "(Loose cube1)"}
    assert {str(a) for a in model.goal(state)} == {"(HandEmpty robot)", "(Placed cube1)"}
    # On the desk in the goal region (desk frame x -0.05-0.15, y 0.12-0.27): Placed.
    z = state.get(cube, "z")
    placed = state.copy()
    move_object(placed, cube, (state.get(desk, "x") + 0.05, 0.2, z))
    assert abstract_atoms(model, placed) == {"(HandEmpty robot)", "(Placed cube1)"}
    assert env.goal(placed)
    # A closed hand with the cube lifted at its pinch point holds it; HandEmpty goes away.
    ctx = model.skills[0].context
    held = state.copy()
    held.set(robot, "pos_gripper", 0.4)
    pinch = pinch_frame(ctx, held)[:3, 3]
    move_object(held, cube, pinch - np.array([0.0, 0.0, 0.01]))
    assert pinch[2] > z + 0.1  # the home pose holds the hand well above the desk
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


def test_ik_reaches_a_downward_pose_and_fails_cleanly_out_of_reach(env) -> None:
    model = create_model(env)
    ctx = model.skills[0].context
    state = env.reset(seed=1000)[0].copy()
    cube = env.objects["cube1"]
    target = np.array([state.get(cube, f) for f in ("x", "y", "z")]) + np.array([0.0, 0.0, 0.1])
    q = solve_ik(ctx, state, target, 0.3, arm_joints(state, ctx.robot))
    for i, v in enumerate(q, start=1):
        state.set(ctx.robot, f"pos_arm_joint{i}", float(v))
    tf = pinch_frame(ctx, state)
    assert np.allclose(tf[:3, 3], target, atol=2e-3)
    assert tf[2, 2] == pytest.approx(-1.0, abs=1e-2)  # the approach axis points down
    assert math.atan2(tf[1, 0], tf[0, 0]) == pytest.approx(0.3, abs=2e-2)
    assert np.allclose(down_quat(0.0), [1.0, 0.0, 0.0, 0.0])
    with pytest.raises(SkillFailure, match="no FR3 IK solution"):
        solve_ik(ctx, state, target + np.array([2.0, 0.0, 0.0]), 0.0, q)


def test_place_is_not_initiable_with_an_open_hand(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Place"))
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(op).controller, state, [0.5, 0.5], env.transition, 10)


class _Unreachable(FrankaController):
    """Closes the hand for at least 3 steps, then asks joint 1 for 3 rad within 2 steps."""

    hand_must_be = "open"

    def plan(self, state):
        q = arm_joints(state, self.objects[0])
        return [
            Move(None, 1.0, tol=1.0, min_steps=3),
            Move(tuple(q + np.array([3.0, 0, 0, 0, 0, 0, 0])), 1.0, max_steps=2),
        ]


def test_move_following_holds_then_fails_on_an_unreached_target(env) -> None:
    state = env.reset(seed=1000)[0]
    controller = _Unreachable((env.objects["robot"],), None)
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
    assert all(a[7] == 1.0 and np.allclose(a[:7], 0.0, atol=0.02) for a in actions[:3])
    assert actions[3][0] == pytest.approx(0.1)  # the delta is clipped to the action bound


@pytest.mark.parametrize("seed", [1001, 1002])
def test_pick_and_place_reach_their_predictions(env, seed: int) -> None:
    model = create_model(env)
    state = env.reset(seed=seed)[0]
    z = state.get(env.objects["cube1"], "z")
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
    assert final.get(env.objects["cube1"], "z") == pytest.approx(z, abs=3e-3)  # on the desk
    assert env.goal_atoms(final) == {"on(cube1, goal_region)": True}


@pytest.mark.slow
def test_planner_solves_an_episode(env) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    reached, stats = plan_reaches_goal(env, 1003, BilevelPlanningArgs(planning_timeout=60))
    assert reached, stats
