"""The Tossing3D (MuJoCo) model: predicates on hand-built states, skills, grounding, planning."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import abstract_atoms, check_planning_model


@pytest.fixture(scope="module")
def env():
    e = make_object_centric("kinder/Tossing3D-o2-v0")
    yield e
    e.close()


def test_predicates_on_hand_built_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert abstract_atoms(model, state) == {
        "(HandEmpty robot)",
        "(OnGround cube_0)",
        "(OnGround cube_1)",
        "(Upright cuboid_barrier)",
    }
    assert {str(a) for a in model.goal(state)} == {"(InBin cube_0 bin_0)", "(InBin cube_1 bin_0)"}
    objs = env.objects
    # The barrier lying on its side (turned 90° about y), cube_0 resting on the bin's floor.
    edited = state.copy()
    half = math.sqrt(0.5)
    for feature, value in (("qw", half), ("qx", 0.0), ("qy", half), ("qz", 0.0), ("z", 0.015)):
        edited.set(objs["cuboid_barrier"], feature, value)
    bin_xy = [state.get(objs["bin_0"], f) for f in ("x", "y")]
    for feature, value in zip(("x", "y", "z"), [*bin_xy, 0.0325], strict=True):
        edited.set(objs["cube_0"], feature, value)
    assert abstract_atoms(model, edited) == {
        "(HandEmpty robot)",
        "(InBin cube_0 bin_0)",
        "(OnGround cube_1)",
        "(Toppled cuboid_barrier)",
    }
    # Half-tipped (45° + a little): neither Upright nor Toppled.
    tipped = state.copy()
    angle = math.radians(50.0)
    for feature, value in (("qw", math.cos(angle / 2)), ("qy", math.sin(angle / 2))):
        tipped.set(objs["cuboid_barrier"], feature, value)
    assert "(Upright cuboid_barrier)" not in abstract_atoms(model, tipped)
    assert "(Toppled cuboid_barrier)" not in abstract_atoms(model, tipped)
    # A closed hand whose pinch point is at cube_1 (lifted) holds it; HandEmpty goes away.
    robot = objs["robot"]
    held = state.copy()
    held.set(robot, "pos_gripper", 0.8)
    pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
    for feature, value in zip(("x", "y", "z"), pinch - np.array([0.0, 0.0, 0.01]), strict=True):
        held.set(objs["cube_1"], feature, value)
    assert abstract_atoms(model, held) == {
        "(Holding robot cube_1)",
        "(OnGround cube_0)",
        "(Upright cuboid_barrier)",
    }


def test_grounding_and_pddl(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    names = sorted(o.name for o in model.ground_operators(state))
    assert names == [
        "Drop(robot, cube_0, bin_0, cuboid_barrier)",
        "Drop(robot, cube_1, bin_0, cuboid_barrier)",
        "DropOver(robot, cube_0, bin_0, cuboid_barrier)",
        "DropOver(robot, cube_1, bin_0, cuboid_barrier)",
        "Pick(robot, cube_0)",
        "Pick(robot, cube_1)",
        "Topple(robot, cuboid_barrier)",
    ]
    domain = model.domain_pddl()
    assert "(:action Topple" in domain and "(:action Drop" in domain
    assert "(:action DropOver" in domain


@pytest.fixture(scope="module")
def env_o1():
    e = make_object_centric("kinder/Tossing3D-o1-v0")
    yield e
    e.close()


def test_skills_reach_their_predictions(env_o1) -> None:
    """Topple, Pick and Drop on o1, whose goal box moves with the bin (the toppled barrier,
    pushed ahead of the base, shoves the 0.1 kg bin along)."""
    env = env_o1
    model = create_model(env)
    state = env.reset(seed=1)[0]
    rng = np.random.default_rng(0)
    plan = ["Topple(robot, cuboid_barrier)", "Pick(robot, cube_0)",
            "Drop(robot, cube_0, bin_0, cuboid_barrier)"]  # fmt: skip
    state = check_planning_model(
        model,
        state,
        plan,
        rng,
        samples=6,  # sample parameters as the planner would
        max_steps=400,
        retry_mispredictions=True,
        require_finished=False,  # the last Drop ends the episode when the cube lands in the bin
        check_action_bounds=True,
        check_params_space=True,
    )
    assert env.goal_atoms(state)["on(cube_0, blocks_goal_region)"]


def test_drop_needs_a_held_cube(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Drop"))
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(op).controller, state, [0.5, 0.5, 0.5], env.transition, 10)


def test_topple_refuses_a_lane_through_the_cubes(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    cube_y = state.get(env.objects["cube_0"], "y")
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Topple"))
    lane = (cube_y + 2.0) / 4.0  # the lane straight through cube_0
    with pytest.raises(SkillFailure, match="blocked"):
        execute_skill(model.skill(op).controller, state, [lane], env.transition, 10)


def test_planner_solves_a_seeded_instance() -> None:
    from kinder_bench.baselines.bilevel_planning import plan_reaches_goal

    e = make_object_centric("kinder/Tossing3D-o1-v0")
    try:
        solved, _ = plan_reaches_goal(e, 1)
    finally:
        e.close()
    assert solved


def test_drop_over_reaches_the_fixed_bin(env) -> None:
    """o2: Pick, then DropOver with the arm stretched over the upright barrier (o2's goal box is
    fixed on the floor where the bin stands, so the bin must not be pushed)."""
    model = create_model(env)
    state = env.reset(seed=1)[0]
    plan = ["Pick(robot, cube_0)", "DropOver(robot, cube_0, bin_0, cuboid_barrier)"]
    state = check_planning_model(
        model,
        state,
        plan,
        np.random.default_rng(0),
        samples=6,
        max_steps=400,
        retry_mispredictions=True,
        check_action_bounds=True,
        check_params_space=True,
    )
    assert env.goal_atoms(state)["on(cube_0, blocks_goal_region)"]
    assert "(Upright cuboid_barrier)" in abstract_atoms(model, state)
