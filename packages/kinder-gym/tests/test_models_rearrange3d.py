"""The Rearrange3D (MuJoCo) model: predicates on hand-built states, skills, and the planner."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_gym.testing import abstract_atoms, move_object

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill

O1 = "kinder/Rearrange3D-o1-put_the_boxed_drink_behind_the_bowl-v0"
O2 = (
    "kinder/Rearrange3D-o2-put_the_can_on_the_left_and_the_boxed_drink_on_the_right_side_of_the_bowl"
    "-v0"
)


@pytest.fixture(scope="module")
def env2():
    e = make_object_centric(O2)
    yield e
    e.close()


def test_predicates_on_hand_built_states(env2) -> None:
    model = create_model(env2)
    state = env2.reset(seed=1000)[0]
    drink, can, bowl = (env2.objects[n] for n in ("boxed_drink_0", "can_0", "bowl_0"))
    assert abstract_atoms(model, state) == {
        "(HandEmpty robot)",
        "(Loose boxed_drink_0)",
        "(Loose can_0)",
    }
    assert {str(a) for a in model.goal(state)} == {
        "(HandEmpty robot)",
        "(Placed boxed_drink_0)",
        "(Placed can_0)",
    }
    # Upstream's sides in the bowl's frame (the bowl stands at yaw 0): left is -y, right +y.
    # The can 9 cm to the bowl's left and the drink 9 cm to its right, standing: both Placed.
    b = np.array([state.get(bowl, f) for f in ("x", "y")])
    can_z, drink_z = state.get(can, "z"), state.get(drink, "z")
    placed = state.copy()
    move_object(placed, can, (b[0], b[1] - 0.09, can_z))
    move_object(placed, drink, (b[0], b[1] + 0.09, drink_z))
    assert abstract_atoms(model, placed) == {
        "(HandEmpty robot)",
        "(Placed boxed_drink_0)",
        "(Placed can_0)",
    }
    assert env2.goal(placed)
    # Swapped sides: neither is in its region.
    swapped = state.copy()
    move_object(swapped, can, (b[0], b[1] + 0.09, can_z))
    move_object(swapped, drink, (b[0], b[1] - 0.09, drink_z))
    assert abstract_atoms(model, swapped) == abstract_atoms(model, state)
    # A closed hand with the can lifted at its pinch point holds it; HandEmpty goes away.
    robot = env2.objects["robot"]
    held = state.copy()
    held.set(robot, "pos_gripper", 0.7)
    pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
    move_object(held, can, pinch - np.array([0.0, 0.0, 0.03]))
    assert abstract_atoms(model, held) == {"(Holding robot can_0)", "(Loose boxed_drink_0)"}
    # Closed on nothing: neither HandEmpty nor Holding.
    fist = state.copy()
    fist.set(robot, "pos_gripper", 0.99)
    assert abstract_atoms(model, fist) == {"(Loose boxed_drink_0)", "(Loose can_0)"}


def test_grounding_and_place_sampler(env2) -> None:
    model = create_model(env2)
    state = env2.reset(seed=1000)[0]
    names = sorted(o.name for o in model.ground_operators(state))
    assert names == [
        "Pick(robot, boxed_drink_0)",
        "Pick(robot, can_0)",
        "Place(robot, boxed_drink_0)",
        "Place(robot, can_0)",
    ]
    op = next(o for o in model.ground_operators(state) if o.name == "Place(robot, can_0)")
    controller = model.skill(op).controller
    rng = np.random.default_rng(0)
    bowl = env2.objects["bowl_0"]
    b = np.array([state.get(bowl, f) for f in ("x", "y")])
    for _ in range(20):
        p = controller.sample_parameters(state, rng)
        assert controller.params_space.contains(p)
        # The can's spot: left of the bowl (-y; upstream's box widened by its 1 cm tolerance),
        # its footprint clear of the bowl's rim.
        spot = b + np.array([-0.06 + 0.12 * p[1], -0.13 + 0.09 * p[2]])
        assert 0.06 + 0.047 + 0.005 <= np.linalg.norm(spot - b) <= 0.15
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(controller, state, [0.5, 0.5, 0.5], env2.transition, 10)


def test_pick_and_place_reach_their_predictions(env2) -> None:
    model = create_model(env2)
    state = env2.reset(seed=1001)[0]
    rng = np.random.default_rng(0)
    ops = {o.name: o for o in model.ground_operators(state)}
    for name in ("Pick(robot, can_0)", "Place(robot, can_0)"):
        before = model.abstract(state)
        for _ in range(3):  # sample parameters as the planner would
            gs = model.skill(ops[name])
            params = gs.controller.sample_parameters(state, rng)
            try:
                out = execute_skill(gs.controller, state, params, env2.transition, 300)
            except SkillFailure:
                continue
            if out.finished and model.abstract(out.states[-1]) == ops[name].apply(before):
                high = env2.action_space.high
                assert all(np.all(np.abs(a) <= high + 1e-9) for a in out.actions)
                state = out.states[-1]
                break
        else:
            raise AssertionError(f"{name} never reached its prediction")
    assert env2.goal_atoms(state)["on(can_0, left_bowl_region)"]


def test_planner_solves_a_seeded_instance() -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    env = make_object_centric(O1)
    reached, stats = plan_reaches_goal(env, 1003, BilevelPlanningArgs(planning_timeout=60))
    assert reached, stats


@pytest.mark.slow
def test_planner_solves_an_o2_instance(env2) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    reached, stats = plan_reaches_goal(env2, 1003, BilevelPlanningArgs(planning_timeout=60))
    assert reached, stats
