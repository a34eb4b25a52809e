"""ScoopPour3D (MuJoCo): the concepts on edited states, the GraspScoop skill reaching
HoldingScoop, the cube Pick/Place skills reaching their operators' predictions, and (slow) the
planner solving a seeded instance (see ``kinder_gym.models.dynamic3d.scoop_pour3d``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.scoop_pour3d import (
    GraspScoopController,
    abstract_atoms,
    grasp_shift,
    handle_centre,
    scoop_context,
)
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import abstract_atoms as model_atoms


@pytest.fixture(scope="module")
def env():
    e = make_object_centric("kinder/ScoopPour3D-o10-v0")
    yield e
    e.close()


def test_concepts_on_edited_states(env) -> None:
    state = env.reset(seed=0)[0]
    ctx = scoop_context(env)
    assert abstract_atoms(ctx, state) == {"(HandEmpty robot)"}
    # A cube moved onto the green bin's floor (2.5 cm above its bottom, the frame of the goal
    # region) counts as InTarget.
    frame = env.regions.transform(state, "target_bin_region")
    moved = state.copy()
    on_floor = frame[:3, :3] @ np.array([0.0, 0.0, 0.025]) + frame[:3, 3]
    for feature, value in zip(("x", "y", "z"), on_floor, strict=True):
        moved.set(ctx.cubes[0], feature, value)
    assert abstract_atoms(ctx, moved) == {"(HandEmpty robot)", f"(InTarget {ctx.cubes[0].name})"}
    # Closed fingers away from the handle hold nothing.
    closed = state.copy()
    closed.set(ctx.robot, "pos_gripper", 0.8)
    assert abstract_atoms(ctx, closed) == set()


def test_handle_centre_is_on_the_handle_side(env) -> None:
    state = env.reset(seed=0)[0]
    ctx = scoop_context(env)
    pos = np.asarray(state[ctx.scoop][:3])
    h = handle_centre(state, ctx.scoop)
    assert abs(np.linalg.norm(h[:2] - pos[:2]) - 0.0175) < 1e-3
    assert h[2] == pytest.approx(pos[2] + 0.032, abs=1e-3)


def test_context_rejects_other_envs() -> None:
    other = make_object_centric("kinder/BalanceBeam3D-o3-v0")
    try:
        with pytest.raises(ValueError, match="scoop_0"):
            scoop_context(other)
    finally:
        other.close()


@pytest.mark.parametrize("seed", [0, 3])
def test_grasp_scoop_reaches_holding(env, seed: int) -> None:
    state = env.reset(seed=seed)[0]
    ctx = scoop_context(env)
    controller = GraspScoopController((ctx.robot, ctx.scoop), ctx)
    rng = np.random.default_rng(seed)
    for _ in range(3):
        params = controller.sample_parameters(state, rng)
        try:
            out = execute_skill(controller, state, params, env.transition, 400)
        except SkillFailure:
            continue
        if out.finished:
            break
    else:
        pytest.fail("GraspScoop did not finish in 3 samples")
    final = out.states[-1]
    assert abstract_atoms(ctx, final) == {"(HoldingScoop robot scoop_0)"}
    high = env.action_space.high
    assert all(np.all(np.abs(a) <= high + 1e-9) for a in out.actions)
    pinch = pinch_position(base_pose(final, ctx.robot), arm_joints(final, ctx.robot))
    assert np.linalg.norm(pinch - handle_centre(final, ctx.scoop)) < 0.02
    # Not initiable with closed fingers.
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(controller, final, params, env.transition, 10)


def test_model_predicates_on_edited_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    cubes = [f"cube_{i}" for i in range(10)]
    start = {"(HandEmpty robot)"} | {f"(InSource {c})" for c in cubes}
    assert model_atoms(model, state) == start
    assert {str(a) for a in model.goal(state)} == {f"(InTarget {c})" for c in cubes}
    frame = env.regions.transform(state, "target_bin_region")
    moved = state.copy()
    on_floor = frame[:3, :3] @ np.array([0.0, 0.0, 0.025]) + frame[:3, 3]
    for feature, value in zip(("x", "y", "z"), on_floor, strict=True):
        moved.set(env.objects["cube_3"], feature, value)
    assert model_atoms(model, moved) == start - {"(InSource cube_3)"} | {"(InTarget cube_3)"}


def test_pick_and_place_reach_their_predictions(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1)[0]
    rng = np.random.default_rng(1)
    ops = {o.name: o for o in model.ground_operators(state)}
    for name in ("Pick(robot, cube_4)", "Place(robot, cube_4)"):
        before = model.abstract(state)
        gs = model.skill(ops[name])
        for _ in range(3):
            params = gs.controller.sample_parameters(state, rng)
            try:
                out = execute_skill(gs.controller, state, params, env.transition, 200)
            except SkillFailure:
                continue
            if out.finished and model.abstract(out.states[-1]) == ops[name].apply(before):
                high = env.action_space.high
                assert all(np.all(np.abs(a) <= high + 1e-9) for a in out.actions)
                state = out.states[-1]
                break
        else:
            pytest.fail(f"{name} did not reach its prediction in 3 samples")
    assert env.goal_atoms(state)["on(cube_4, target_bin_region)"]


def test_pick_next_to_the_bin_wall(env) -> None:
    """A cube 7 cm from the yellow bin's wall with the fingers closing across the wall: opened
    wide, the finger links landed on the wall's top and the descent stalled (seed 9's cube_0);
    opened to the pre-grasp width they reach the cube."""
    model = create_model(env)
    state = env.reset(seed=9)[0]
    wall_y = state.get(env.objects["bin_yellow_0"], "y") + 0.15  # the wall nearer the green bin
    cube = env.objects["cube_0"]
    for feature, value in zip(
        ("x", "y", "qw", "qz"), (0.555, wall_y - 0.07, 1.0, 0.0), strict=True
    ):
        state.set(cube, feature, value)  # faces square to the wall: the pads close across it
    for i, other in enumerate(o for o in env.objects.values() if o.name.startswith("cube_")):
        if other != cube:  # the others well away from it
            state.set(other, "x", 0.40 + 0.02 * i)
            state.set(other, "y", wall_y - 0.25)
    op = next(o for o in model.ground_operators(state) if o.name == "Pick(robot, cube_0)")
    gs = model.skill(op)
    out = execute_skill(gs.controller, state, np.array([0.5]), env.transition, 200)
    assert out.finished and model.abstract(out.states[-1]) == op.apply(model.abstract(state))


def test_grasp_shift_keeps_a_touching_cube_out_of_the_pads(env) -> None:
    state = env.reset(seed=2)[0]
    ctx = scoop_context(env)
    cube, other = env.objects["cube_4"], env.objects["cube_9"]
    for i, o in enumerate(ctx.cubes):  # all apart, 10 cm from cube_4
        state.set(o, "x", 0.40 + 0.03 * i)
        state.set(o, "y", -0.30)
    state.set(cube, "x", 0.50)
    state.set(cube, "y", -0.20)
    for feature, value in zip(("qw", "qx", "qy", "qz"), (1.0, 0.0, 0.0, 0.0), strict=True):
        state.set(cube, feature, value)  # square to the axes: the Pick's heading is 0
    assert np.all(grasp_shift(ctx, state, cube, 0.0) == 0.0)
    # Touching along the closing direction (y at heading 0): it would sit under a pad whatever
    # the shift, so no grasp at this heading; turned a quarter, the pads close along x and the
    # pinch point moves along their width, away from it.
    state.set(other, "x", 0.50)
    state.set(other, "y", -0.20 + 0.0105)
    assert grasp_shift(ctx, state, cube, 0.0) is None
    shift = grasp_shift(ctx, state, cube, math.pi / 2)
    assert shift is not None and shift[1] < 0.0 and abs(shift[1]) <= 0.006 + 1e-9
    # Touching along the pads' width (x): the pinch point moves along x instead.
    state.set(other, "x", 0.50 + 0.0105)
    state.set(other, "y", -0.20)
    shift = grasp_shift(ctx, state, cube, 0.0)
    assert shift is not None and shift[0] < 0.0 and shift[1] == 0.0
    # Planning the shifted grasp leaves the state alone (it once moved the cube in place).
    model = create_model(env)
    op = next(o for o in model.ground_operators(state) if o.name == "Pick(robot, cube_4)")
    before = state.copy()
    execute_skill(model.skill(op).controller, state, np.array([0.5]), env.transition, 1)
    assert np.array_equal(state.data, before.data)


# Slow (about a minute): the planner simulates ~900 actions of ten cubes.
@pytest.mark.slow
def test_planner_solves_a_seeded_instance(env) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    # A budget the check does not depend on: a plan simulates about 900 actions of ten cubes
    # (41 s of planning on a loaded 2-core machine). A development seed: on MuJoCo 3.3.7 at
    # 0.5 ms, evaluation seed 0's pile leaves a cube whose pick motion never converges (the
    # planner gives up on it), which the benchmark's figures count, not this check.
    args = BilevelPlanningArgs(planning_timeout=600.0)
    solved, _ = plan_reaches_goal(env, seed=1000, args=args)
    assert solved
