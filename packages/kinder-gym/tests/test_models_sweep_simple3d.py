"""The SweepSimple3D (MuJoCo) model: predicates on edited states, skills, the planner."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.sweep_simple3d import PASS_CLEARANCE, _base_ok, _clear, _turn_ok
from kinder_gym.models.dynamic3d.tidybot import (
    BASE_FEATURES,
    HOME,
    arm_joints,
    base_pose,
    pinch_position,
)
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


def test_base_clearance_of_the_kitchen_fixtures() -> None:
    assert _base_ok(np.array([1.5, 1.5]))
    assert not _base_ok(np.array([1.0, 0.0]))  # 12.5 cm from the island's side
    assert not _base_ok(np.array([2.0, 0.0]))  # the chassis would hit the cooking counter
    assert not _base_ok(np.array([1.5, 2.2]))  # ... or the side counter
    assert _base_ok(np.array([0.5, 1.3]))  # past the island's end
    # Past the cooking counter's end, where one o50 task's goal area lies, the floor is free.
    assert _base_ok(np.array([2.6, -1.4]))
    assert not _base_ok(np.array([2.6, -1.1]))


def test_a_path_that_starts_too_near_a_fixture_may_only_back_away() -> None:
    def path(a, b):
        return np.linspace(a, b, 7)

    near = (1.0, 0.0)  # 12.5 cm from the island's side, inside the 23 cm clearance
    assert _clear(path(near, (1.4, 0.0)), PASS_CLEARANCE)  # away from the island
    assert _clear(path(near, (1.0, 0.5)), PASS_CLEARANCE)  # along it, no nearer
    assert not _clear(path(near, (0.95, 0.3)), PASS_CLEARANCE)  # nearer
    assert not _clear(path((1.5, 0.0), (1.0, 0.0)), PASS_CLEARANCE)  # from clear into it


def test_pick_slides_the_base_where_it_cannot_turn(env) -> None:
    # Where a place leaves the base: past the island's end, facing +x. Turning to face -y there
    # swings the folded hand over the island, so a pick first slides the base away.
    model = create_model(env)
    state = env.reset(seed=0)[0].copy()
    robot = env.objects["robot"]
    for feature, value in zip(BASE_FEATURES, (0.22, 1.26, 0.0), strict=True):
        state.set(robot, feature, value)
    folded = pinch_position(np.zeros(3), HOME)[:2]
    assert not _turn_ok(np.array([0.22, 1.26]), 0.0, -np.pi / 2, folded)
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Pick"))
    controller = model.skill(op).controller
    rng = np.random.default_rng(0)
    routes = []
    for _ in range(200):
        try:
            routes.append(controller.geometry(state, rng.random(3))[2])
        except SkillFailure:
            continue
    assert routes, "no pick parameters were clear from beside the island"
    # A route that starts with a slide has a planned-on-the-fly drive before the turn segment.
    assert any(callable(r[0]) and not hasattr(r[0], "base") for r in routes)


def test_a_neighbour_closed_on_with_the_block_stays_to_be_moved() -> None:
    e = make_object_centric(O1.replace("-o1-", "-o5-"))
    try:
        model = create_model(e)
        state = e.reset(seed=0)[0]
        robot, a, b = e.objects["robot"], e.objects["cube_0"], e.objects["cube_1"]
        held = state.copy()
        held.set(robot, "pos_gripper", 0.9)
        pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
        for cube, dx in ((a, 0.005), (b, 0.02)):  # cube_0 nearer the pinch point
            for feature, value in zip(("x", "y", "z"), pinch + np.array([dx, 0.0, 0.0])):
                held.set(cube, feature, value)
        got = {str(x) for x in model.abstract(held)}
        assert "(Holding robot cube_0)" in got and "(OnFloor cube_1)" in got
        # Both let down in the goal area: Place(cube_0) predicted cube_0 InArea; cube_1 InArea
        # too is accepted (InArea is monotone, its negation OnFloor may vanish with it).
        from kinder_gym.model import abstract_match

        place = next(o for o in model.ground_operators(held) if o.name == "Place(robot, cube_0)")
        expected = place.apply(model.abstract(held))
        down = state.copy()
        for cube, x in ((a, 0.4), (b, 0.45)):
            down.set(cube, "x", x)
            down.set(cube, "y", 1.2)
        reached = model.abstract(down)
        assert "(InArea cube_1)" in {str(x) for x in reached}
        assert abstract_match(model, reached, expected)
    finally:
        e.close()


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


#: Upstream's floor regions are widened by 5 cm on every side when it checks a goal.
UPSTREAM_MARGIN = np.array([-0.05, -0.05, 0.05, 0.05])


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
        assert ctx.box == pytest.approx(np.add(box, UPSTREAM_MARGIN))  # upstream's ranges
    finally:
        e.close()
