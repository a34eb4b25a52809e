"""Motion2D and StickButton2D models: predicates, collision checking, skills, registry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinder_core import make_object_centric
from kinder_garden2d.kinematic2d.object_types import BUTTON_GREEN
from kinder_gym.models import create_model, family_of
from kinder_gym.models.kinematic2d.crv import CRVCollisionChecker
from kinder_gym.models.kinematic2d.motion2d import passage_gaps
from kinder_gym.skills import SkillFailure, execute_skill
from kinder_gym.testing import check_planning_model


def _skill_reaches_prediction(model, state, name):  # type: ignore[no-untyped-def]
    """Run the named ground skill with sampled params; return the final state."""
    rng = np.random.default_rng(0)
    return check_planning_model(model, state, [name], rng, stop_on_goal=False, monotone_extras=True)


def test_motion2d_predicates_on_hand_built_states() -> None:
    env = make_object_centric("kinder/Motion2D-p1-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    region = env.target_region
    inside = state.copy()
    inside.set(env.robot, "x", state.get(region, "x") + 0.1)
    inside.set(env.robot, "y", state.get(region, "y") + 0.1)
    assert {str(a) for a in model.abstract(inside)} == {"(AtTarget robot target_region)"}
    assert {str(a) for a in model.abstract(state)} == {"(NotAtTarget robot target_region)"}
    assert {str(a) for a in model.goal(state)} == {"(AtTarget robot target_region)"}
    gaps = passage_gaps(state, 0.0, 2.5)
    assert len(gaps) == 1 and gaps[0][2] - gaps[0][1] >= 0.2


def test_collision_checker_agrees_with_the_env() -> None:
    rng = np.random.default_rng(0)
    for env_id in ("kinder/Motion2D-p3-v0", "kinder/StickButton2D-b3-v0"):
        env = make_object_centric(env_id)
        for seed in range(3):
            state = env.reset(seed=seed)[0]
            checker = CRVCollisionChecker(env.world, state)
            for _ in range(300):
                q = [
                    rng.uniform(0, 3.5),
                    rng.uniform(0, 2.5),
                    rng.uniform(-math.pi, math.pi),
                    rng.uniform(0.1, 0.2),
                ]
                assert checker(q) == (not env.world.in_collision(checker.data_at(q))), q


def test_motion2d_skill_reaches_the_target() -> None:
    env = make_object_centric("kinder/Motion2D-p2-v0")
    model = create_model(env)
    state = env.reset(seed=4)[0]
    final = _skill_reaches_prediction(model, state, "MoveToTarget(robot, target_region)")
    assert env.goal_reached(final)


def test_motion2d_goal_in_collision_fails() -> None:
    env = make_object_centric("kinder/Motion2D-p0-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    op = model.ground_operators(state)[0]
    gs = model.skill(op)
    # u = 0.9 of the region's width puts the base centre against the right wall (x > 2.4).
    region_x = state.get(env.target_region, "x")
    assert region_x + 0.9 * 0.25 > 2.4
    with pytest.raises(SkillFailure, match="in collision"):
        execute_skill(gs.controller, state, [0.9, 0.5, 0.5], env.transition, 100)


def test_stickbutton2d_predicates_on_hand_built_states() -> None:
    env = make_object_centric("kinder/StickButton2D-b2-v0")
    model = create_model(env)
    state = env.reset(seed=1)[0]
    b0, b1 = env.buttons
    state.set(b0, "y", 0.5)
    state.set(b1, "y", 2.0)
    for k, v in zip(("color_r", "color_g", "color_b"), BUTTON_GREEN):
        state.set(b1, k, v)
    atoms = {str(a) for a in model.abstract(state)}
    assert atoms == {
        "(HandEmpty robot)",
        "(OnFloor button0)",
        "(OnTable button1)",
        "(Pressed button1)",
    }
    assert {str(a) for a in model.goal(state)} == {"(Pressed button0)", "(Pressed button1)"}


def test_stickbutton2d_skills_chain() -> None:
    env = make_object_centric("kinder/StickButton2D-b3-v0")
    model = create_model(env)
    state = env.reset(seed=2)[0]
    floor = [b for b in env.buttons if state.get(b, "y") < env.config.table_min_y]
    table = [b for b in env.buttons if state.get(b, "y") >= env.config.table_min_y]
    assert floor and table  # this seed has both kinds
    state = _skill_reaches_prediction(model, state, f"RobotPress(robot, {floor[0].name})")
    state = _skill_reaches_prediction(model, state, "PickStick(robot, stick)")
    assert "(Grasped robot stick)" in {str(a) for a in model.abstract(state)}
    state = _skill_reaches_prediction(model, state, f"StickPress(robot, stick, {table[0].name})")
    state = _skill_reaches_prediction(model, state, "PlaceStick(robot, stick)")
    assert "(HandEmpty robot)" in {str(a) for a in model.abstract(state)}


def test_stickbutton2d_stick_without_area_fails_the_pick_cleanly() -> None:
    """A noisy observation clipped to a zero stick width leaves no face to grasp: the pick skill
    fails like any unreachable sample (no NaN from the face geometry)."""
    env = make_object_centric("kinder/StickButton2D-b1-v0")
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    state.set(env.stick, "width", 0.0)
    pick = next(op for op in model.ground_operators(state) if op.name.startswith("PickStick"))
    controller = model.skill(pick).controller
    for face in (0.1, 0.5, 0.9):  # the end face and both long faces
        with np.errstate(all="raise"), pytest.raises(SkillFailure, match="no area"):
            controller.goal_config(state, np.array([face, 0.5, 0.5]))


def test_registry() -> None:
    env = make_object_centric("kinder/StickButton2D-b1-v0")
    assert family_of(env) == "StickButton2D"
    env.spec = None
    assert family_of(env) == "StickButton2D"  # from the registered entry point
    with pytest.raises(ValueError, match="No planning model for Nope"):
        create_model(env, family="Nope")
    assert "(:action StickPress" in create_model(env).domain_pddl()


def test_2d_parts_import_without_the_3d_package() -> None:
    import subprocess
    import sys

    code = (
        "import sys, kinder_gym, kinder_gym.models, kinder_gym.motion_planning\n"
        "import kinder_gym.models.kinematic2d.motion2d\n"
        "import kinder_gym.models.kinematic2d.stickbutton2d\n"
        "import kinder_gym.models.dynamic2d.dyn_obstruction2d\n"
        "import kinder_gym.models.dynamic2d.dyn_pushpullhook2d\n"
        "bad = [m for m in ('kinder_garden3d', 'pybullet', 'mujoco') if m in sys.modules]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
