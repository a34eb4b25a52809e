"""ClutteredStorage2D model: predicates, grounding, skills, and the bilevel planner on it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinder_core import ObjectCentricState, make_object_centric
from kinder_garden2d.kinematic2d.predicates import is_inside_shelf
from kinder_gym.model import PlanningModel
from kinder_gym.models import create_model
from kinder_gym.models.kinematic2d.clutteredstorage2d import obstructs
from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import check_planning_model


def _atoms(model: PlanningModel, state: ObjectCentricState) -> set[str]:
    return {str(a) for a in model.abstract(state)}


def _run(model: PlanningModel, state: ObjectCentricState, name: str, seed: int = 0):  # type: ignore[no-untyped-def]
    """Run the named ground skill with sampled params (up to 5 samples); check that it reaches
    its operator's predicted abstract state exactly; return the final state."""
    rng = np.random.default_rng(seed)
    return check_planning_model(model, state, [name], rng, samples=5, stop_on_goal=False)


def _place_block(
    state: ObjectCentricState, block: object, cx: float, cy: float, theta: float
) -> None:
    """Move a rectangle so that its centre is (cx, cy) and its angle theta."""
    w, h = state.get(block, "width"), state.get(block, "height")  # type: ignore[arg-type]
    c, s = math.cos(theta), math.sin(theta)
    state.set(block, "x", cx - 0.5 * (c * w - s * h))  # type: ignore[arg-type]
    state.set(block, "y", cy - 0.5 * (s * w + c * h))  # type: ignore[arg-type]
    state.set(block, "theta", theta)  # type: ignore[arg-type]


def test_predicates_on_hand_built_states() -> None:
    env = make_object_centric("kinder/ClutteredStorage2D-b3-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    b0, b1, b2 = env.blocks
    shelf = env.shelf
    assert _atoms(model, state) == {
        "(HandEmpty robot)",
        "(OnShelf block0 shelf)",
        "(NotOnShelf block1 shelf)",
        "(NotOnShelf block2 shelf)",
        "(ShelfCluttered shelf)",
    }
    assert {str(a) for a in model.goal(state)} == {f"(OnShelf block{i} shelf)" for i in range(3)}
    x1, w1 = state.get(shelf, "x1"), state.get(shelf, "width1")
    top = state.get(shelf, "y1") + state.get(shelf, "height1")
    # The stored block lifted to the top of the opening, level: the shelf is clear.
    lifted = state.copy()
    _place_block(lifted, b0, x1 + 0.5 * w1, top - 0.03, 0.0)
    assert is_inside_shelf(lifted, b0, shelf) and not obstructs(lifted, b0, shelf)
    assert "(ShelfClear shelf)" in _atoms(model, lifted)
    # A block standing upright low in the opening does not obstruct; a flat one does.
    upright = lifted.copy()
    _place_block(upright, b1, x1 + 0.05, state.get(shelf, "y1") + 0.16, math.pi / 2)
    assert {"(OnShelf block1 shelf)", "(ShelfClear shelf)"} <= _atoms(model, upright)
    flat = lifted.copy()
    _place_block(flat, b1, x1 + 0.5 * w1, state.get(shelf, "y1") + 0.05, 0.1)
    assert {"(OnShelf block1 shelf)", "(ShelfCluttered shelf)"} <= _atoms(model, flat)
    # A block half outside the opening is not on the shelf.
    out = state.copy()
    _place_block(out, b2, x1, state.get(shelf, "y1") + 0.1, math.pi / 2)
    assert "(NotOnShelf block2 shelf)" in _atoms(model, out)
    # Suction on with a block in the zone: holding it.
    held = state.copy()
    rx, ry = state.get(env.robot, "x"), state.get(env.robot, "y")
    held.set(env.robot, "theta", 0.0)
    held.set(env.robot, "vacuum", 1.0)
    tip = rx + state.get(env.robot, "arm_joint") + 0.5 * state.get(env.robot, "gripper_width")
    _place_block(held, b2, tip + 0.015 + 0.14, ry, 0.0)
    assert {"(Holding robot block2)"} <= _atoms(model, held)
    assert "(HandEmpty robot)" not in _atoms(model, held)


def test_grounding() -> None:
    env = make_object_centric("kinder/ClutteredStorage2D-b3-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    names = sorted(o.name for o in model.ground_operators(state))
    assert names == sorted(
        ["ClearShelf(robot, shelf)"]
        + [
            f"{op}(robot, block{i}, shelf)"
            for op in ("PickFromFloor", "PlaceInShelf")
            for i in range(3)
        ]
    )
    assert "(define (domain clutteredstorage2d)" in model.domain_pddl()


def test_skills_chain_to_the_goal() -> None:
    env = make_object_centric("kinder/ClutteredStorage2D-b3-v0")
    model = create_model(env)
    state = env.reset(seed=1)[0]
    state = _run(model, state, "ClearShelf(robot, shelf)")
    assert not obstructs(state, env.blocks[0], env.shelf)
    for i in (1, 2):
        state = _run(model, state, f"PickFromFloor(robot, block{i}, shelf)")
        state = _run(model, state, f"PlaceInShelf(robot, block{i}, shelf)")
    assert env.goal_reached(state)


def test_clear_shelf_fails_on_a_clear_shelf() -> None:
    env = make_object_centric("kinder/ClutteredStorage2D-b1-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    op = model.ground_operators(state)[0]
    assert op.name == "ClearShelf(robot, shelf)"
    assert not op.applicable(model.abstract(state))
    gs = model.skill(op)
    with pytest.raises(SkillFailure):
        execute_skill(gs.controller, state, [0.0], env.transition, 10)


def _solves(env_id: str, seeds: list[int]) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    env = make_object_centric(env_id)
    for seed in seeds:
        reached, stats = plan_reaches_goal(env, seed, BilevelPlanningArgs(planning_timeout=30))
        assert reached, (env_id, seed, stats)


def test_planner_solves_small_seeded_instances() -> None:
    _solves("kinder/ClutteredStorage2D-b1-v0", [0, 1])
    _solves("kinder/ClutteredStorage2D-b3-v0", [2, 3])


@pytest.mark.slow
def test_planner_solves_large_seeded_instances() -> None:
    _solves("kinder/ClutteredStorage2D-b7-v0", [0, 1])
    _solves("kinder/ClutteredStorage2D-b15-v0", [0])


def test_tilted_shifted_end_grasp_still_inserts_upright() -> None:
    env = make_object_centric("kinder/ClutteredStorage2D-b1-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    ops = {o.name: o for o in model.ground_operators(state)}
    pick = model.skill(ops["PickFromFloor(robot, block0, shelf)"])
    out = execute_skill(
        pick.controller, state, [0.2, 0.3, 0.9, 0.9], env.transition, model.max_skill_horizon
    )
    state = out.states[-1]
    assert "(Holding robot block0)" in _atoms(model, state)
    # The block is held at π/12 · 0.8 off the arm's axis.
    rel = math.remainder(state.get(env.blocks[0], "theta") - state.get(env.robot, "theta"), math.pi)
    assert abs(abs(rel) - 0.8 * math.pi / 12) < 1e-6
    state = _run(model, state, "PlaceInShelf(robot, block0, shelf)")
    assert env.goal_reached(state)
    assert abs(math.cos(state.get(env.blocks[0], "theta"))) < 1e-6
