"""The ConstrainedCupboard3D (MuJoCo) model: predicates on hand-built states, skills, grounding
and a planned episode."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from kinder_gym.testing import abstract_atoms

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.constrained_cupboard3d import (
    _base_for_rod,
    _rod_bottom,
    _rod_elevation,
    _rod_in_base,
)
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill


@pytest.fixture(scope="module")
def env():
    e = make_object_centric("kinder/ConstrainedCupboard3D-o2-v0")
    yield e
    e.close()


def _set_pose(state, obj, position, quat=None) -> None:
    for feature, value in zip(("x", "y", "z"), position, strict=True):
        state.set(obj, feature, float(value))
    if quat is not None:
        for feature, value in zip(("qw", "qx", "qy", "qz"), quat, strict=True):
            state.set(obj, feature, float(value))


def test_predicates_on_hand_built_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    on_ground = {"(OnGround cuboid_0)", "(OnGround cuboid_1)"}
    assert abstract_atoms(model, state) == {"(HandEmpty robot)"} | on_ground
    assert {str(a) for a in model.goal(state)} == {
        "(HandEmpty robot)",
        "(OnShelf cuboid_0 cupboard_1)",
        "(OnShelf cuboid_1 cupboard_1)",
    }
    # cuboid_0 lying on shelf 0 of cupboard_1, 5 cm inside the opening: OnShelf, not OnGround,
    # although its centre (3.5 cm) is as low as a rod on the floor could be tilted.
    frame = env.regions.transform(state, "cupboard_1_shelf_0_goal_region")
    on_shelf = state.copy()
    _set_pose(on_shelf, env.objects["cuboid_0"], frame[:3, :3] @ [0.0, 0.1, 0.015] + frame[:3, 3])
    assert abstract_atoms(model, on_shelf) == {
        "(HandEmpty robot)",
        "(OnShelf cuboid_0 cupboard_1)",
        "(OnGround cuboid_1)",
    }
    assert env.goal_atoms(on_shelf)["on(cuboid_0, cupboard_1_shelf_0_goal_region)"]
    # The same rod beside the cupboard at that height is on no shelf, and not on the ground.
    beside = on_shelf.copy()
    _set_pose(beside, env.objects["cuboid_0"], frame[:3, 3] + np.array([-0.4, 0.0, 0.1]))
    assert abstract_atoms(model, beside) == {"(HandEmpty robot)", "(OnGround cuboid_1)"}
    # A closed hand whose pinch point is on the rod's axis near one end (lifted) holds it.
    robot = env.objects["robot"]
    held = state.copy()
    held.set(robot, "pos_gripper", 0.85)
    base = base_pose(held, robot)
    pinch = pinch_position(base, arm_joints(held, robot))
    heading = np.array([math.cos(base[2]), math.sin(base[2]), 0.0])
    yaw = float(base[2]) - math.pi / 2  # the rod's length (its local y) along the heading
    quat = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
    _set_pose(held, env.objects["cuboid_1"], pinch + 0.055 * heading, quat)
    assert abstract_atoms(model, held) == {"(Holding robot cuboid_1)", "(OnGround cuboid_0)"}
    # Closed on nothing: neither HandEmpty nor Holding.
    empty_fist = state.copy()
    empty_fist.set(robot, "pos_gripper", 0.99)
    assert abstract_atoms(model, empty_fist) == on_ground


def test_rod_geometry_helpers(env) -> None:
    state = env.reset(seed=0)[0].copy()
    rod, robot = env.objects["cuboid_0"], env.objects["robot"]
    # Rod along +x, its +x end raised 30° about the y axis: the rod's local y is its length.
    yaw, tilt = -math.pi / 2, math.radians(30)
    qz = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    qy = np.array([math.cos(-tilt / 2), 0.0, math.sin(-tilt / 2), 0.0])
    w1, x1, y1, z1 = qy
    w2, x2, y2, z2 = qz
    quat = (
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    )
    _set_pose(state, rod, (1.0, 0.0, 0.2), quat)
    assert _rod_elevation(state, rod, 0.0) == pytest.approx(tilt, abs=1e-9)
    assert _rod_elevation(state, rod, math.pi) == pytest.approx(-tilt, abs=1e-9)
    # Lowest point: the bottom edge of the lower end (the rod's width stays horizontal).
    low = 0.2 - 0.15 * math.sin(tilt) - 0.015 * math.cos(tilt)
    assert _rod_bottom(state, rod) == pytest.approx(low, abs=1e-9)
    # The base pose that puts a rod held at (local, angle) where asked, axis along `yaw`.
    _set_pose(state, rod, (1.0, 0.0, 0.015), qz)
    for feature, value in zip(("pos_base_x", "pos_base_y", "pos_base_rot"), (0.2, 0.1, 0.3)):
        state.set(robot, feature, value)
    local, angle = _rod_in_base(state, robot, rod)
    assert abs(angle) <= math.pi / 2
    pose = _base_for_rod(local, angle, np.array([1.0, 0.0]), 0.0)
    np.testing.assert_allclose(pose, [0.2, 0.1, 0.3], atol=1e-9)


def test_grounding_and_pddl(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    names = sorted(o.name for o in model.ground_operators(state))
    assert names == [
        "Pick(robot, cuboid_0)",
        "Pick(robot, cuboid_1)",
        "Place(robot, cuboid_0, cupboard_1)",
        "Place(robot, cuboid_1, cupboard_1)",
    ]
    domain = model.domain_pddl()
    assert "(:action Pick" in domain and "(:action Place" in domain
    assert "(OnShelf cuboid_1 cupboard_1)" in model.problem_pddl(state)


def test_pick_and_place_reach_their_predictions(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1)[0]
    rng = np.random.default_rng(0)
    ops = {o.name: o for o in model.ground_operators(state)}
    for name in ("Pick(robot, cuboid_0)", "Place(robot, cuboid_0, cupboard_1)"):
        before = model.abstract(state)
        for _ in range(4):  # sample parameters as the planner would
            gs = model.skill(ops[name])
            params = gs.controller.sample_parameters(state, rng)
            assert gs.controller.params_space.contains(params.astype(np.float32))
            try:
                out = execute_skill(
                    gs.controller, state, params, env.transition, 400, stop_on_goal=False
                )
            except SkillFailure:
                continue
            if out.finished and model.abstract(out.states[-1]) == ops[name].apply(before):
                high = env.action_space.high
                assert all(np.all(np.abs(a) <= high + 1e-9) for a in out.actions)
                state = out.states[-1]
                break
        else:
            raise AssertionError(f"{name} never reached its prediction")
    assert env.goal_atoms(state)["on(cuboid_0, cupboard_1_shelf_0_goal_region)"]
    # The rod lies level along the cupboard's depth, and the hand is back outside.
    rod = env.objects["cuboid_0"]
    assert abs(_rod_elevation(state, rod, 0.0)) < math.radians(5)
    assert state.get(rod, "z") == pytest.approx(0.035, abs=0.005)


def test_place_is_not_initiable_with_an_open_hand(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Place"))
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(op).controller, state, [0.5], env.transition, 10)


def test_unsupported_goal_is_a_clear_error() -> None:
    e = make_object_centric("kinder/ConstrainedCupboard3D-o1-v0")
    e.task = dataclasses.replace(e.task, goal=("and", [("in", "robot", "x")]))
    with pytest.raises(ValueError, match="unsupported goal atom"):
        create_model(e)


def test_planner_solves_a_seeded_instance() -> None:
    from kinder_bench.baselines.bilevel_planning import plan_reaches_goal

    e = make_object_centric("kinder/ConstrainedCupboard3D-o3-v0")
    solved, stats = plan_reaches_goal(e, seed=0)
    assert solved, stats
