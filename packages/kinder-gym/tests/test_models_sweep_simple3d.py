"""The SweepSimple3D (MuJoCo) model: predicates on edited states, skills, the planner."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.sweep_simple3d import _base_ok
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill

O1 = "kinder/SweepSimple3D-o1-sweep_the_blocks_to_the_left_side_of_the_kitchen_island-v0"


@pytest.fixture(scope="module")
def env():
    e = make_object_centric(O1)
    yield e
    e.close()


def atoms(model, state) -> set[str]:
    return {str(a) for a in model.abstract(state)}


def test_predicates_on_edited_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert atoms(model, state) == {"(HandEmpty robot)", "(OnFloor cube_0)"}
    assert {str(a) for a in model.goal(state)} == {"(HandEmpty robot)", "(InArea cube_0)"}
    cube, robot = env.objects["cube_0"], env.objects["robot"]
    # The block moved into the goal box (left of the island) is InArea, no longer OnFloor.
    inside = state.copy()
    inside.set(cube, "x", 0.5)
    inside.set(cube, "y", 1.2)
    assert atoms(model, inside) == {"(HandEmpty robot)", "(InArea cube_0)"}
    assert env.goal_atoms(inside)["on(cube_0, sweep_region)"]
    # A closed hand whose pinch point is at the (lifted) block holds it.
    held = state.copy()
    held.set(robot, "pos_gripper", 0.9)
    pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
    for feature, value in zip(("x", "y", "z"), pinch - np.array([0.0, 0.0, 0.01]), strict=True):
        held.set(cube, feature, value)
    assert atoms(model, held) == {"(Holding robot cube_0)"}
    # Closed on nothing: neither HandEmpty nor Holding.
    fist = state.copy()
    fist.set(robot, "pos_gripper", 0.99)
    assert atoms(model, fist) == {"(OnFloor cube_0)"}


def test_base_clearance_of_the_island_and_the_room() -> None:
    assert _base_ok(np.array([1.5, 1.5]))
    assert not _base_ok(np.array([1.0, 0.0]))  # 12.5 cm from the island's side
    assert not _base_ok(np.array([2.0, 0.0]))  # the chassis would hit the cooking counter
    assert _base_ok(np.array([0.5, 1.3]))  # past the island's end


def test_pick_and_place_reach_their_predictions(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1)[0]
    rng = np.random.default_rng(0)
    ops = {o.name: o for o in model.ground_operators(state)}
    assert sorted(ops) == ["Pick(robot, cube_0)", "Place(robot, cube_0)"]
    for name in ("Pick(robot, cube_0)", "Place(robot, cube_0)"):
        before = model.abstract(state)
        for _ in range(3):  # sample parameters as the planner would
            gs = model.skill(ops[name])
            params = gs.controller.sample_parameters(state, rng)
            assert gs.controller.params_space.contains(params.astype(np.float32))
            try:
                # Not stopped at the goal: the held block enters the goal box before it is let go.
                out = execute_skill(
                    gs.controller, state, params, env.transition, 400, stop_on_goal=False
                )
            except SkillFailure:
                continue
            if out.finished and model.abstract(out.states[-1]) == ops[name].apply(before):
                state = out.states[-1]
                break
        else:
            raise AssertionError(f"{name} never reached its prediction")
    assert env.goal_atoms(state)["on(cube_0, sweep_region)"]


def test_place_is_not_initiable_with_an_open_hand(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Place"))
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(op).controller, state, [0.5] * 4, env.transition, 10)


def test_planner_solves_a_seeded_instance(env) -> None:
    from kinder_bench.baselines.bilevel_planning import plan_reaches_goal

    solved, _ = plan_reaches_goal(env, seed=2)
    assert solved


@pytest.mark.parametrize(
    ("task", "box"),
    [
        ("left_side_of_the_kitchen_island", (0.125, 1.0, 0.875, 1.375)),
        ("right_side_of_the_kitchen_island", (0.125, -1.375, 0.875, -1.0)),
        ("right_side_of_the_kitchen_counter", (2.245, -1.375, 2.995, -1.0)),
    ],
)
def test_every_goal_area_is_read_from_the_task(task, box) -> None:
    e = make_object_centric(f"kinder/SweepSimple3D-o50-sweep_the_blocks_to_the_{task}-v0")
    try:
        model = create_model(e)
        state = e.reset(seed=0)[0]
        assert len(model.goal(state)) == 51  # 50 blocks InArea, and HandEmpty
        ctx = model.skills[0].context
        assert ctx.box == pytest.approx(box)
    finally:
        e.close()
