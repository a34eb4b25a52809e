"""The ClutteredRetrieval2D planning model: predicates, grounding, skills and planning."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from kinder_core import ObjectCentricState, make_object_centric
from kinder_gym.concepts import sorted_atoms
from kinder_gym.model import PlanningModel
from kinder_gym.models import create_model
from kinder_gym.models.kinematic2d.clutteredretrieval2d import (
    PickTargetController,
    find_blockers,
    rectangle_faces,
)
from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import check_planning_model


def _run(model: PlanningModel, state: ObjectCentricState, name: str) -> Any:
    """Run the named ground skill (up to 5 parameter samples, as a planner would); check that
    the first execution that finishes reaches its operator's prediction."""
    rng = np.random.default_rng(0)
    return check_planning_model(model, state, [name], rng, samples=5, stop_on_goal=False)


def test_faces_are_outward_facing_sides() -> None:
    env = make_object_centric("kinder/ClutteredRetrieval2D-o1-v0")
    state = env.reset(seed=0)[0]
    block = env.target_block
    faces = rectangle_faces(state, block)
    th = state.get(block, "theta")
    centre = np.array([state.get(block, "x"), state.get(block, "y")]) + 0.07 * np.array(
        [math.cos(th) - math.sin(th), math.sin(th) + math.cos(th)]
    )
    for face in faces:
        assert face.length == pytest.approx(0.14)
        # The inward normal points from the face's middle to the centre, 0.07 m away.
        assert np.allclose(face.mid + 0.07 * face.inward, centre)
        assert abs(float(face.tangent @ face.inward)) < 1e-12


def test_predicates_on_hand_built_states() -> None:
    env = make_object_centric("kinder/ClutteredRetrieval2D-o1-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    obstruction, region, target = env.obstructions[0], env.target_region, env.target_block
    # Far from the block and the region: nothing is in the way.
    far = state.copy()
    bx, by = far.get(target, "x"), far.get(target, "y")
    far.set(obstruction, "x", 0.05 if bx > 1.25 else 2.3)
    far.set(obstruction, "y", 0.05 if by > 1.25 else 2.3)
    far.set(obstruction, "theta", 0.0)
    assert not find_blockers(env, far).in_the_way
    assert sorted_atoms(model.abstract(far)) == ["(Blockers0)", "(HandEmpty robot)"]
    # On the region: it blocks, whichever face is chosen.
    on_region = far.copy()
    for k in ("x", "y", "theta"):
        on_region.set(obstruction, k, state.get(region, k))
    assert find_blockers(env, on_region).blocking == {obstruction}
    assert sorted_atoms(model.abstract(on_region)) == [
        "(Blocked)",
        "(Blockers1)",
        "(HandEmpty robot)",
    ]
    # The block inside the region (aligned, centred) satisfies the goal atom.
    inside = far.copy()
    rth = state.get(region, "theta")
    off = 0.035 * np.array([math.cos(rth) - math.sin(rth), math.sin(rth) + math.cos(rth)])
    inside.set(target, "x", state.get(region, "x") + off[0])
    inside.set(target, "y", state.get(region, "y") + off[1])
    inside.set(target, "theta", rth)
    assert "(Inside target_block target_region)" in sorted_atoms(model.abstract(inside))
    assert sorted_atoms(model.goal(state)) == ["(Inside target_block target_region)"]
    # The robot at a grasp pose of the block with the vacuum on holds it.
    holding = far.copy()
    pick = PickTargetController((env.robot, target), env)
    goal = pick.goal_config(holding, np.array([0.1, 0.5, 1.0]))
    assert goal is not None
    for k, v in zip(("x", "y", "theta", "arm_joint", "vacuum"), [*goal, 1.0]):
        holding.set(env.robot, k, float(v))
    atoms = sorted_atoms(model.abstract(holding))
    assert "(HoldingTgt robot target_block)" in atoms and "(HandEmpty robot)" not in atoms


def test_grounding() -> None:
    env = make_object_centric("kinder/ClutteredRetrieval2D-o10-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    names = sorted(o.name for o in model.ground_operators(state))
    assert names == sorted(
        [
            "PickObstruction(robot)",
            *(f"PlaceObstruction{k}(robot)" for k in range(1, 11)),
            "PickTgt(robot, target_block)",
            "PlaceTgt(robot, target_block, target_region)",
        ]
    )
    atoms = sorted_atoms(model.abstract(state))
    k = len(find_blockers(env, state).blocking)
    assert k >= 1 and "(Blocked)" in atoms
    assert [a for a in atoms if a.startswith("(Blockers")] == [f"(Blockers{k})"]


def test_skills_reach_their_predictions() -> None:
    env = make_object_centric("kinder/ClutteredRetrieval2D-o1-v0")
    model = create_model(env)
    state = env.reset(seed=1001)[0]
    # This seed's obstruction blocks the target block's most accessible face.
    assert find_blockers(env, state).blocking == {env.obstructions[0]}
    state = _run(model, state, "PickObstruction(robot)")
    assert env.obstructions[0] in env.held_objects(state)
    state = _run(model, state, "PlaceObstruction1(robot)")
    state = _run(model, state, "PickTgt(robot, target_block)")
    gs = model.skill(
        next(o for o in model.ground_operators(state) if o.name.startswith("PlaceTgt"))
    )
    params = gs.controller.sample_parameters(state, np.random.default_rng(0))
    out = execute_skill(gs.controller, state, params, env.transition, model.max_skill_horizon)
    assert out.terminated and env.goal_reached(out.states[-1])


def test_pick_rejects_a_grasp_touching_two_objects() -> None:
    env = make_object_centric("kinder/ClutteredRetrieval2D-o1-v0")
    state = env.reset(seed=0)[0]
    pick = PickTargetController((env.robot, env.target_block), env)
    params = np.array([0.1, 0.5, 1.0])
    goal = pick.goal_config(state, params)
    assert goal is not None
    # A sliver of obstruction 1-2 mm in front of the grasped face's middle: inside the suction
    # zone (which reaches 2.5 mm out of the face), clear of the gripper (7.5 mm out).
    face = rectangle_faces(state, env.target_block)[0]
    obstruction = env.obstructions[0]
    spot = face.mid - 0.002 * face.inward - 0.02 * face.tangent
    state.set(obstruction, "theta", math.atan2(face.tangent[1], face.tangent[0]))
    state.set(obstruction, "x", float(spot[0]))
    state.set(obstruction, "y", float(spot[1]))
    state.set(obstruction, "width", 0.01)
    state.set(obstruction, "height", 0.001)
    assert env.world.in_collision(state.data) is False
    with pytest.raises(SkillFailure, match="intended outcome"):
        execute_skill(pick, state, params, env.transition, 600)


@pytest.mark.parametrize(
    ("env_id", "seeds"),
    [("kinder/ClutteredRetrieval2D-o1-v0", (0, 5)), ("kinder/ClutteredRetrieval2D-o10-v0", (0,))],
)
def test_planner_solves_seeded_instances(env_id: str, seeds: tuple[int, ...]) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    env = make_object_centric(env_id)
    for seed in seeds:
        reached, stats = plan_reaches_goal(env, seed, BilevelPlanningArgs(planning_timeout=30))
        assert reached, (env_id, seed, stats)


@pytest.mark.slow
def test_planner_solves_most_o10_instances() -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    env = make_object_centric("kinder/ClutteredRetrieval2D-o10-v0")
    solved = 0
    for seed in range(10):
        solved += plan_reaches_goal(env, seed, BilevelPlanningArgs(planning_timeout=60))[0]
    assert solved >= 7
