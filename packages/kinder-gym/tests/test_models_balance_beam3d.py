"""The BalanceBeam3D (MuJoCo) model: predicates on edited states, the torque-aware sampler, the
skills reaching their predictions, and the planner solving a seeded instance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinder_gym.testing import abstract_atoms

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.balance_beam3d import REACH, SAMPLER_ANGLE
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill

BLOCKS = ("large_block", "small_block_1", "small_block_2")


@pytest.fixture(scope="module")
def env():
    e = make_object_centric("kinder/BalanceBeam3D-o3-v0")
    yield e
    e.close()


def _put_on_beam(env, state, name: str, u: float):
    """``state`` with block ``name`` resting ``u`` metres along the beam from its centre."""
    frame = env.regions.transform(state, "beam_goal_region")
    size = state.get(env.objects[name], "bb_z")
    p = frame[:3, :3] @ np.array([u, 0.0, 0.005 + size / 2]) + frame[:3, 3]
    out = state.copy()
    for feature, value in zip(("x", "y", "z"), p, strict=True):
        out.set(env.objects[name], feature, value)
    return out


def test_predicates_on_edited_states(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    start = {"(HandEmpty robot)", "(Balanced seesaw_1)"} | {f"(OnGround {b})" for b in BLOCKS}
    assert abstract_atoms(model, state) == start
    assert {str(a) for a in model.goal(state)} == {
        "(HandEmpty robot)",
        "(Balanced seesaw_1)",
    } | {f"(OnBeam {b} seesaw_1)" for b in BLOCKS}
    on_beam = _put_on_beam(env, state, "large_block", 0.05)
    assert abstract_atoms(model, on_beam) == start - {"(OnGround large_block)"} | {
        "(OnBeam large_block seesaw_1)"
    }
    # The beam tilted by 6° (over the goal's 5°): Balanced goes away.
    tilted = state.copy()
    tilted.set(env.objects["seesaw_1"], "hinge_pos", math.radians(6.0))
    assert abstract_atoms(model, tilted) == start - {"(Balanced seesaw_1)"}
    # A closed hand whose pinch point is at a lifted block holds it.
    robot = env.objects["robot"]
    held = state.copy()
    held.set(robot, "pos_gripper", 0.85)
    pinch = pinch_position(base_pose(held, robot), arm_joints(held, robot))
    for feature, value in zip(("x", "y", "z"), pinch, strict=True):
        held.set(env.objects["small_block_1"], feature, value)
    assert abstract_atoms(model, held) == {
        "(Holding robot small_block_1)",
        "(Balanced seesaw_1)",
        "(OnGround large_block)",
        "(OnGround small_block_2)",
    }


def test_place_sampler_keeps_the_estimated_beam_level(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    # The large block (100 g) sits 10 cm out: the small block must go to the other side.
    state = _put_on_beam(env, state, "large_block", 0.10)
    ops = {o.name: o for o in model.ground_operators(state)}
    controller = model.skill(ops["Place(robot, small_block_1, seesaw_1)"]).controller
    rng = np.random.default_rng(0)
    for _ in range(20):
        params = controller.sample_parameters(state, rng)
        assert controller.params_space.contains(params.astype(np.float32))
        u = REACH * (2 * float(params[0]) - 1)
        torque = 9.81 * (0.1 * 0.10 + 0.05 * u)
        assert abs(torque) / 1.2 < SAMPLER_ANGLE
        assert u < 0.0


def test_pick_and_place_reach_their_predictions(env) -> None:
    model = create_model(env)
    state = env.reset(seed=1)[0]
    rng = np.random.default_rng(0)
    ops = {o.name: o for o in model.ground_operators(state)}
    for name in ("Pick(robot, large_block)", "Place(robot, large_block, seesaw_1)"):
        before = model.abstract(state)
        for _ in range(6):  # sample parameters as the planner would
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
    assert env.goal_atoms(state)["on(large_block, beam_goal_region)"]
    assert env.goal_atoms(state)["balanced(seesaw_1, 5)"]


def test_place_is_not_initiable_with_an_open_hand(env) -> None:
    model = create_model(env)
    state = env.reset(seed=0)[0]
    op = next(o for o in model.ground_operators(state) if o.name.startswith("Place"))
    with pytest.raises(SkillFailure, match="not initiable"):
        execute_skill(model.skill(op).controller, state, [0.5], env.transition, 10)


def test_planner_solves_a_seeded_instance(env) -> None:
    from kinder_bench.baselines.bilevel_planning import plan_reaches_goal

    solved, _ = plan_reaches_goal(env, seed=1)
    assert solved
