"""The SortClutteredBlocks3D (MuJoCo) model: predicates, the pad check, skills, the planner."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinder_gym.testing import abstract_atoms, move_object

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.sort_cluttered_blocks3d import _grasp_shift, _pads_clear
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill

O4 = "kinder/SortClutteredBlocks3D-o4-sort_the_cluttered_blocks_into_bins-v0"
O12 = "kinder/SortClutteredBlocks3D-o12-sort_the_blocks_into_the_cupboard-v0"
BOWLS = "kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bowls-v0"


@pytest.fixture(scope="module")
def env():
    e = make_object_centric(O4)
    yield e
    e.close()


def test_predicates_on_hand_built_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    loose = {f"(Loose cube{i})" for i in range(1, 5)}
    assert abstract_atoms(model, state) == {"(HandEmpty robot)"} | loose
    assert {str(a) for a in model.goal(state)} == {"(HandEmpty robot)"} | {
        f"(Sorted cube{i})" for i in range(1, 5)
    }
    red, green = env.objects["bin_red"], env.objects["bin_green"]
    cube1 = env.objects["cube1"]
    # cube1 (red, by the colour cycle) on the red bin's floor: Sorted; in the green bin: not.
    # (The 2 cm cube rests 2 cm above the bin's frame, its bottom face on the 0.4 m table.)
    sorted_ = state.copy()
    move_object(sorted_, cube1, (state.get(red, "x"), state.get(red, "y"), 0.42))
    assert abstract_atoms(model, sorted_) == {"(HandEmpty robot)", "(Sorted cube1)"} | (
        loose - {"(Loose cube1)"}
    )
    wrong = state.copy()
    move_object(wrong, cube1, (state.get(green, "x"), state.get(green, "y"), 0.42))
    assert abstract_atoms(model, wrong) == abstract_atoms(model, state)
    # A closed hand with cube2 lifted at the pinch point holds it.
    robot = env.objects["robot"]
    held = state.copy()
    held.set(robot, "pos_gripper", 0.9)
    pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
    move_object(held, env.objects["cube2"], pinch - np.array([0.0, 0.0, 0.02]))
    assert abstract_atoms(model, held) == {"(Holding robot cube2)"} | (loose - {"(Loose cube2)"})


def test_grounding_and_the_cupboard_variant_has_its_own_model(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    names = sorted(o.name for o in model.ground_operators(state))
    assert names == sorted(
        [f"Pick(robot, cube{i})" for i in range(1, 5)]
        + [f"Drop(robot, cube{i})" for i in range(1, 5)]
    )
    cupboard = make_object_centric(O12)
    assert create_model(cupboard).name == "sort_cupboard3d"  # test_models_sort_cupboard3d.py
    cupboard.close()


def test_pads_check_sees_a_cube_between_the_pads(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    cube1, cube2 = env.objects["cube1"], env.objects["cube2"]
    ctx = model.skills[0].context
    move_object(state, cube1, (0.0, 0.0, 0.41))
    for i in (2, 3, 4):  # every other cube far away
        move_object(state, env.objects[f"cube{i}"], (0.2, 0.2 * i, 0.41))
    assert _pads_clear(ctx, state, cube1, 0.0)
    # cube2 (2 cm) touching cube1 along y. Heading pi/2: the pads close along x and would clamp
    # both cubes side by side; heading 0: they close along y, and cube2 lies outside the gap.
    move_object(state, cube2, (0.0, 0.02, 0.41))
    assert not _pads_clear(ctx, state, cube1, math.pi / 2)
    assert _pads_clear(ctx, state, cube1, 0.0)
    # ... unless the pinch point moves 5 mm (a quarter of the cube) away from cube2 along the
    # pads' width.
    assert _grasp_shift(ctx, state, cube1, math.pi / 2) == pytest.approx(-0.005)
    assert _grasp_shift(ctx, state, cube1, 0.0) == 0.0
    # Stacked on cube1: between the pads whichever way they close.
    move_object(state, cube2, (0.0, 0.0, 0.43))
    assert not _pads_clear(ctx, state, cube1, 0.0)
    assert not _pads_clear(ctx, state, cube1, math.pi / 2)
    assert _grasp_shift(ctx, state, cube1, 0.0) is None
    # The top cube's pads close above cube1, so it can be picked first.
    assert _pads_clear(ctx, state, cube2, 0.0)


def test_pick_and_drop_reach_their_predictions(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1001)[0]
    rng = np.random.default_rng(0)
    ops = {o.name: o for o in model.ground_operators(state)}
    for name in ("Pick(robot, cube2)", "Drop(robot, cube2)"):
        before = model.abstract(state)
        for _ in range(3):  # sample parameters as the planner would
            gs = model.skill(ops[name])
            params = gs.controller.sample_parameters(state, rng)
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
    assert env.goal_atoms(state)["on(cube2, bin_green_goal_region)"]
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(ops["Drop(robot, cube1)"]).controller, state, [0.5, 0.5],
                      env.transition, 10)  # fmt: skip


@pytest.mark.slow
def test_a_cube_is_dropped_into_its_bowl() -> None:
    """Upstream's bowl goals are table squares, each with its bowl's centre in it: the Drop
    aims at the bowl (near its centre), and the cube ends inside it and over its square."""
    env = make_object_centric(BOWLS)
    model = create_model(env)
    state = env.reset(seed=1001)[0]
    rng = np.random.default_rng(0)
    ops = {o.name: o for o in model.ground_operators(state)}
    for name in ("Pick(robot, cube6)", "Drop(robot, cube6)"):
        before = model.abstract(state)
        for _ in range(3):
            controller = model.skill(ops[name]).controller
            params = controller.sample_parameters(state, rng)
            try:
                out = execute_skill(controller, state, params, env.transition, 400)
            except SkillFailure:
                continue
            if out.finished and model.abstract(out.states[-1]) == ops[name].apply(before):
                state = out.states[-1]
                break
        else:
            raise AssertionError(f"{name} never reached its prediction")
    cube, bowl = env.objects["cube6"], env.objects["bowl_green"]
    assert env.goal_atoms(state)["on(cube6, bowl_green_goal_region)"]
    offset = [state.get(cube, f) - state.get(bowl, f) for f in ("x", "y")]
    assert float(np.hypot(*offset)) < 0.5 * state.get(bowl, "bb_x") - 0.01
    assert state.get(cube, "z") < state.get(bowl, "z")  # below the rim: in the bowl
    env.close()


def test_planner_solves_a_seeded_instance(env) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    reached, stats = plan_reaches_goal(env, 1000, BilevelPlanningArgs(planning_timeout=60))
    assert reached, stats
