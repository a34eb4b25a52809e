"""The SweepIntoDrawer3D planning model: abstraction on hand-built states, the operators' effects
reached by the skills in simulation, and the goal atoms matching the env's goal."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_core import ObjectCentricState
from kinder_garden3d.dynamic3d.env import Dynamic3DEnv
from kinder_gym.concepts import sorted_atoms
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic3d.sweep_into_drawer3d import (
    DRAWER,
    HEAD_SIDE,
    TABLE_Z,
    SweepController,
    create_model,
    head_bottom,
    unwrap,
    wiper_pose,
)
from kinder_gym.skills import execute_skill

TASK = "SweepIntoDrawer3D/SweepIntoDrawer3D.json"
OPEN = f"OpenDrawer(robot, {DRAWER})"
PICK = f"PickWiper(robot, wiper_0, {DRAWER})"


@pytest.fixture(scope="module")
def env() -> Dynamic3DEnv:
    e = Dynamic3DEnv(TASK, num_objects=5)
    yield e
    e.close()


@pytest.fixture(scope="module")
def model(env: Dynamic3DEnv) -> PlanningModel:
    return create_model(env)


def _start(env: Dynamic3DEnv, seed: int = 0) -> ObjectCentricState:
    return env.reset(seed=seed)[0]


def _run(model: PlanningModel, state: ObjectCentricState, name: str, seed: int = 0):
    op = {o.name: o for o in model.ground_operators(state)}[name]
    skill = model.skill(op)
    params = skill.controller.sample_parameters(state, np.random.default_rng(seed))
    rollout = execute_skill(skill.controller, state, params, model.env.transition, 300)
    return op, rollout


def test_initial_abstraction_and_goal(env, model):
    s = _start(env)
    assert sorted_atoms(model.abstract(s)) == [f"(DrawerClosed {DRAWER})", "(HandEmpty robot)"]
    assert sorted_atoms(model.goal(s)) == [f"(InDrawer cube_{i})" for i in range(5)]
    names = sorted(o.name for o in model.ground_operators(s))
    assert names == sorted(
        [OPEN, PICK, *(f"Sweep(robot, wiper_0, {DRAWER}, cube_{i})" for i in range(5))]
    )
    assert "InDrawer" in model.monotone_predicates
    assert "(:action Sweep" in model.domain_pddl()


def test_drawer_and_screw_predicates_on_hand_built_states(env, model):
    s = _start(env).copy()
    drawer = env.objects[DRAWER]
    s.set(drawer, "pos", 0.3)
    atoms = sorted_atoms(model.abstract(s))
    assert f"(DrawerOpen {DRAWER})" in atoms and f"(DrawerClosed {DRAWER})" not in atoms
    # A screw inside the open drawer (the region slides out with it) is InDrawer; on the
    # floor it is Lost; back on the island top it is neither.
    screw = env.objects["cube_0"]
    for f, v in zip(("x", "y", "z"), (0.5 + 0.3 + 0.2, 0.0, 0.22), strict=True):
        s.set(screw, f, v)
    assert "(InDrawer cube_0)" in sorted_atoms(model.abstract(s))
    s.set(screw, "z", 0.01)
    atoms = sorted_atoms(model.abstract(s))
    assert "(Lost cube_0)" in atoms and "(InDrawer cube_0)" not in atoms
    s.set(screw, "z", 0.467)
    atoms = sorted_atoms(model.abstract(s))
    assert not any("cube_0" in a for a in atoms)


def test_goal_atoms_imply_the_env_goal(env, model):
    s = _start(env).copy()
    for i in range(5):
        screw = env.objects[f"cube_{i}"]
        for f, v in zip(("x", "y", "z"), (0.3 + 0.08 * i, -0.1 + 0.05 * i, 0.22), strict=True):
            s.set(screw, f, v)
    assert model.goal(s) <= model.abstract(s)
    assert env.goal_reached(s)


def test_holding_needs_closed_fingers_near_the_wiper(env, model):
    s = _start(env).copy()
    robot = env.objects["robot"]
    s.set(robot, "pos_gripper", 0.85)  # closed on something, but far from the wiper
    assert "(HandEmpty robot)" in sorted_atoms(model.abstract(s))


def test_unwrap_moves_continuous_joints_only():
    ref = np.array([3.0, 0.5, 3.0, -1.0, 0.0, 1.0, -3.0])
    q = np.array([-3.0, 0.6, -3.1, -1.1, 6.2, 1.1, 3.0])
    out = unwrap(q, ref)
    assert np.allclose(out[[1, 3, 5]], q[[1, 3, 5]])
    assert np.all(np.abs(out - ref) < 0.4)


def test_open_drawer_reaches_its_predicted_abstract_state(env, model):
    s = _start(env)
    op, rollout = _run(model, s, OPEN)
    assert rollout.finished
    end = rollout.states[-1]
    assert model.abstract(end) == op.apply(model.abstract(s))
    assert end.get(env.objects[DRAWER], "pos") > 0.12


def test_sweep_sampler_prefers_offsets_covering_more_screws(env, model):
    s = _start(env).copy()
    target = env.objects["cube_0"]
    ty = s.get(target, "y")
    for i in range(1, 5):  # all the other screws 5 cm to the +y side of the target
        s.set(env.objects[f"cube_{i}"], "y", ty + 0.05)
    op = {o.name: o for o in model.ground_operators(s)}[f"Sweep(robot, wiper_0, {DRAWER}, cube_0)"]
    controller = model.skill(op).controller
    rng = np.random.default_rng(0)
    for _ in range(5):
        params = controller.sample_parameters(s, rng)
        assert controller.params_space.contains(params)
        # Offsets below −0.03 would leave the other four screws off the head's inner 16 cm.
        assert params[0] >= -0.03


def test_head_bottom_of_the_resting_wiper_is_on_the_top(env):
    s = _start(env)
    assert abs(head_bottom(s, env.objects["wiper_0"]) - TABLE_Z) < 0.003
    lifted = s.copy()
    lifted.set(env.objects["wiper_0"], "z", s.get(env.objects["wiper_0"], "z") + 0.05)
    assert head_bottom(lifted, env.objects["wiper_0"]) - head_bottom(s, env.objects["wiper_0"]) == (
        pytest.approx(0.05)
    )


def test_sweep_sampler_gathers_when_screws_lie_far_back(env, model):
    s = _start(env).copy()
    op = {o.name: o for o in model.ground_operators(s)}[f"Sweep(robot, wiper_0, {DRAWER}, cube_0)"]
    controller = model.skill(op).controller
    counts = []
    for x in (0.65, 0.84):  # every screw far behind the front edge, or all close to it
        for i in range(5):
            s.set(env.objects[f"cube_{i}"], "x", x)
        rng = np.random.default_rng(0)
        counts.append(sum(controller.sample_parameters(s, rng)[4] >= 0.5 for _ in range(40)))
    assert counts[0] >= 24 and counts[1] <= 16, counts


@pytest.mark.slow
def test_pick_wiper_then_sweep(env, model):
    s = _start(env)
    s = _run(model, s, OPEN)[1].states[-1]
    op, rollout = _run(model, s, PICK)
    assert rollout.finished
    held = rollout.states[-1]
    assert model.abstract(held) == op.apply(model.abstract(s))
    assert held.get(env.objects["wiper_0"], "z") > 0.5
    # PickWiper already turned the wiper for sweeping: the direction from its handle to its head
    # (body x times HEAD_SIDE) points along world +x, toward the island's front edge, so the
    # handle trails.
    assert HEAD_SIDE * wiper_pose(held, env.objects["wiper_0"])[1][0, 0] > 0.9
    # A sweep pass keeps the wiper in hand and pushes the band's screws forward (+x).
    op = {o.name: o for o in model.ground_operators(held)}[
        f"Sweep(robot, wiper_0, {DRAWER}, cube_1)"
    ]
    skill = model.skill(op)
    assert isinstance(skill.controller, SweepController)
    params = np.array([0.0, 0.01, 0.04, 0.0, 0.0])  # one pass, no gathering push
    rollout = execute_skill(skill.controller, held, params, env.transition, 300)
    end = rollout.states[-1]
    # The pass may sweep every cube in and end the episode before the skill's last segment.
    assert rollout.finished or (rollout.terminated and env.goal_reached(end))
    assert "(Holding robot wiper_0)" in sorted_atoms(model.abstract(end))
    x0 = held.get(env.objects["cube_1"], "x")
    moved = end.get(env.objects["cube_1"], "x") - x0
    assert moved > 0.05 or end.get(env.objects["cube_1"], "z") < 0.41
