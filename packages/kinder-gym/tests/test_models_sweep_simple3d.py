"""The SweepSimple3D (MuJoCo) model: predicates on edited states, skills, the planner."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_gym.testing import abstract_atoms

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


def test_predicates_on_edited_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    assert abstract_atoms(model, state) == {
        "(HandEmpty robot)",
        "(Free wiper_0)",
        "(OnFloor cube_0)",
    }
    assert {str(a) for a in model.goal(state)} == {"(InArea cube_0)"}
    cube, robot, wiper = env.objects["cube_0"], env.objects["robot"], env.objects["wiper_0"]
    # The block moved into the goal box (left of the island) is InArea, no longer OnFloor.
    inside = state.copy()
    inside.set(cube, "x", 0.5)
    inside.set(cube, "y", 1.2)
    assert abstract_atoms(model, inside) == {
        "(HandEmpty robot)",
        "(Free wiper_0)",
        "(InArea cube_0)",
    }
    assert env.goal_atoms(inside)["on(cube_0, sweep_region)"]
    # A closed hand at the standing wiper's head, 8 cm from its middle, holds it.
    held = state.copy()
    held.set(robot, "pos_gripper", 0.8)
    pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
    for feature, value in zip(("x", "y", "z"), pinch - np.array([0.08, 0.0, 0.02]), strict=True):
        held.set(wiper, feature, value)
    assert abstract_atoms(model, held) == {"(Holding robot wiper_0)", "(OnFloor cube_0)"}
    # The same wiper tipped over is not held.
    tipped = held.copy()
    for feature, value in zip(("qw", "qx", "qy", "qz"), (0.707, 0.707, 0.0, 0.0), strict=True):
        tipped.set(wiper, feature, value)
    assert abstract_atoms(model, tipped) == {"(Free wiper_0)", "(OnFloor cube_0)"}
    # Closed on nothing: neither HandEmpty nor Holding.
    fist = state.copy()
    fist.set(robot, "pos_gripper", 0.99)
    assert abstract_atoms(model, fist) == {"(Free wiper_0)", "(OnFloor cube_0)"}


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
    # Past the island's end, facing +x: turning to face -y there swings the folded hand over
    # the island, so the drive to the wiper first slides the base away.
    model = create_model(env)
    state = env.reset(seed=1000)[0].copy()
    robot = env.objects["robot"]
    for feature, value in zip(BASE_FEATURES, (0.22, 1.26, 0.0), strict=True):
        state.set(robot, feature, value)
    folded = pinch_position(np.zeros(3), HOME)[:2]
    assert not _turn_ok(np.array([0.22, 1.26]), 0.0, -np.pi / 2, folded)
    op = next(o for o in model.ground_operators(state) if o.name == "PickWiper(robot, wiper_0)")
    controller = model.skill(op).controller
    rng = np.random.default_rng(0)
    routes = []
    for _ in range(200):
        try:
            routes.append(controller.geometry(state, rng.random(3)))
        except SkillFailure:
            continue
    assert routes, "no pick parameters were clear from beside the island"
    # A route that starts with a slide has a planned-on-the-fly drive before the turn segment.
    assert any(callable(r[0]) and not hasattr(r[0], "base") for r in routes)


def test_pick_wiper_and_sweep_reach_their_predictions(env) -> None:
    """The wiper is taken by its head and the block pulled along y, then along x, into the
    goal area (development seed 1002)."""
    model = create_model(env)
    state = env.reset(seed=1002)[0]
    rng = np.random.default_rng(0)
    ops = {o.name: o for o in model.ground_operators(state)}
    names = ("PickWiper(robot, wiper_0)", "Sweep(robot, wiper_0, cube_0)")
    assert set(names) <= set(ops)
    for name in names:
        before = model.abstract(state)
        for _ in range(3):  # sample parameters as the planner would
            gs = model.skill(ops[name])
            params = gs.controller.sample_parameters(state, rng)
            assert gs.controller.params_space.contains(params.astype(np.float32))
            try:
                out = execute_skill(
                    gs.controller, state, params, env.transition, 800, stop_on_goal=False
                )
            except SkillFailure:
                continue
            if out.finished and model.abstract(out.states[-1]) == ops[name].apply(before):
                state = out.states[-1]
                break
        else:
            raise AssertionError(f"{name} never reached its prediction")
    assert env.goal_atoms(state)["on(cube_0, sweep_region)"]


def test_sweep_is_not_initiable_with_an_open_hand(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Sweep"))
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(op).controller, state, [0.5] * 3, env.transition, 10)


@pytest.mark.slow
def test_planner_solves_a_seeded_instance(env) -> None:
    from kinder_bench.baselines.bilevel_planning import plan_reaches_goal

    solved, _ = plan_reaches_goal(env, seed=1002)
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
        state = e.reset(seed=1000)[0]
        assert len(model.goal(state)) == 50  # 50 blocks InArea
        ctx = model.skills[0].context
        assert ctx.box == pytest.approx(np.add(box, UPSTREAM_MARGIN))  # upstream's ranges
    finally:
        e.close()
