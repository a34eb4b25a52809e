"""Dynamic2D mechanics under upstream's PD controller (the default): how far an action moves the
robot, velocity features, grasp, carry and release, pushing, static contacts, non-graspable
objects; the kept linear controller; exact replay; goal predicates; config validation.

That every id draws upstream's initial states and makes upstream's transitions is checked against
recorded upstream runs in ``test_conformance_dynamic2d.py``.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

from kinder_core import ObjectCentricState, make, make_object_centric
from kinder_garden2d.dynamic2d.dyn_obstruction2d import DynObstruction2DEnv
from kinder_garden2d.dynamic2d.dyn_pushpullhook2d import DynPushPullHook2DEnv
from kinder_garden2d.dynamic2d.dyn_pusht2d import DynPushT2DEnv
from kinder_garden2d.dynamic2d.dyn_scooppour2d import DynScoopPour2DEnv

TABLE = 0.1


def _obstruction_scene(config: dict[str, Any] | None = None) -> DynObstruction2DEnv:
    """DynObstruction2D-o0 with a 0.2 × 0.3 block standing at x = 1.5 and the robot pointing down
    above it, the gripper base 0.05 above the block's top, fingers open."""
    env = DynObstruction2DEnv(num_obstructions=0, config=config)
    s, _ = env.reset(seed=0)
    b, r = env.target_block, env.robot
    s[b][:6] = (1.5, TABLE + 0.15, 0.0, 0.0, 0.0, 0.0)
    s.set(b, "width", 0.2)
    s.set(b, "height", 0.3)
    s.set(env.target_surface, "x", 2.8)
    s[r][:3] = (1.5, TABLE + 0.3 + 0.05 + s.get(r, "arm_joint"), -math.pi / 2)
    env.set_state(s)
    return env


def _act(env: Any, n: int, **deltas: float) -> ObjectCentricState:
    keys = ["dx", "dy", "dtheta", "darm", "dgripper"]
    a = np.array([deltas.get(k, 0.0) for k in keys])
    s = None
    for _ in range(n):
        s, *_ = env.step(a)
    assert s is not None
    return s


def test_an_action_moves_the_robot_most_of_the_way_and_reports_its_velocity() -> None:
    env = _obstruction_scene()
    r = env.robot
    s0 = env.get_state()
    s0.set(r, "y", 1.5)  # free space
    env.set_state(s0)
    s1 = _act(env, 1, dx=0.05)
    moved = s1.get(r, "x") - s0.get(r, "x")
    assert 0.9 * 0.05 < moved < 1.05 * 0.05  # the PD controller's ten control steps
    assert s1.get(r, "vx_base") != 0.0  # the controller's velocity at the end of the action
    # The velocity features feed the next action's controller.
    fast = s0.copy()
    fast.set(r, "vx_base", 0.3)
    s_fast, _, _ = env.transition(fast, np.array([0.05, 0.0, 0.0, 0.0, 0.0]))
    assert s_fast.get(r, "x") != s1.get(r, "x")


def test_grasp_carry_release() -> None:
    env = _obstruction_scene()
    b, r = env.target_block, env.robot
    s = _act(env, 4, dgripper=-0.02)  # the fingers (0.26 apart) close on the 0.2 block
    assert s.get(b, "held") == 1.0
    rel = s[b][:2] - s[r][:2]
    s = _act(env, 8, dy=0.05)
    s = _act(env, 4, dx=0.05)
    assert s.get(b, "held") == 1.0
    np.testing.assert_allclose(s[b][:2] - s[r][:2], rel, atol=1e-4)  # carried rigidly
    assert s.get(b, "y") > TABLE + 0.15 + 0.3
    s = _act(env, 1, dgripper=0.02)  # opening releases it
    assert s.get(b, "held") == 0.0
    s = _act(env, 10)
    assert s.get(b, "y") == pytest.approx(TABLE + 0.15, abs=0.01)  # fell back onto the table


def test_push_without_grasp() -> None:
    env = _obstruction_scene()
    b, r = env.target_block, env.robot
    s = env.get_state()
    # The base (radius 0.24) at the block's left, at block height, arm pointing up (the arm's
    # bar reaches 0.27 behind the base's centre: it must clear the table).
    s[r][:3] = (1.5 - 0.1 - 0.24 - 0.02, TABLE + 0.3, math.pi / 2)
    env.set_state(s)
    x0 = s.get(b, "x")
    s = _act(env, 10, dx=0.05)
    assert s.get(b, "x") > x0 + 0.3
    assert s.get(b, "held") == 0.0


def test_static_contact_reverts_the_robot() -> None:
    env = _obstruction_scene()
    r = env.robot
    s = env.get_state()
    s.set(env.target_block, "x", 0.6)  # out of the way
    env.set_state(s)
    reach = s.get(r, "arm_joint") + s.get(r, "finger_width")
    ys = []
    for _ in range(30):
        s, *_ = env.step(np.array([0.0, -0.05, 0.0, 0.0, 0.0]))
        ys.append(s.get(r, "y"))
        # The fingertips never enter the table (beyond pymunk's collision slop).
        assert s.get(r, "y") - reach >= TABLE - 0.01
    assert ys[-1] == pytest.approx(ys[-5], abs=1e-3)  # stopped at the table


def test_small_objects_are_never_grasped() -> None:
    env = DynScoopPour2DEnv(num_objects=2)
    s, _ = env.reset(seed=0)
    r = env.robot
    sq = env.squares[0]
    s[sq][:6] = (2.5, 0.044, 0.0, 0.0, 0.0, 0.0)
    s[r][:3] = (2.5, 0.088 + 0.03 + s.get(r, "arm_joint"), -math.pi / 2)
    env.set_state(s)
    for _ in range(15):
        s, *_ = env.step(np.array([0.0, 0.0, 0.0, 0.0, -0.015]))
        assert s.get(sq, "held") == 0.0


def test_scoop_handle_is_grasped_and_lifted() -> None:
    env = DynScoopPour2DEnv(num_objects=2)
    s, _ = env.reset(seed=0)
    r, h = env.robot, env.hook
    hx, hy = s.get(h, "x"), s.get(h, "y")
    # Fingers around the top of the upright handle.
    s[r][:3] = (hx - 0.025, hy + 0.45 + s.get(r, "arm_joint") + 0.04, -math.pi / 2)
    env.set_state(s)
    for _ in range(12):
        s, *_ = env.step(np.array([0.0, 0.0, 0.0, 0.0, -0.015]))
    assert s.get(h, "held") == 1.0
    s = _act(env, 10, dy=0.03)
    assert s.get(h, "y") > hy + 0.25


@pytest.mark.slow
@pytest.mark.parametrize(
    ("env_id", "steps"),
    [
        ("kinder/DynObstruction2D-o3-v0", 300),
        ("kinder/DynPushT2D-t1-v0", 300),
        ("kinder/DynPushPullHook2D-o5-v0", 300),
        ("kinder/DynScoopPour2D-o20-v0", 200),
    ],
)
def test_random_steps_stay_finite(env_id: str, steps: int) -> None:
    env = make(env_id)
    env.reset(seed=1001)
    env.action_space.seed(1001)
    rng = np.random.default_rng(1001)
    for t in range(steps):
        # Mostly random; sometimes a burst of one repeated extreme action (drives into walls).
        if rng.uniform() < 0.7:
            a = env.action_space.sample()
        else:
            a = np.sign(rng.normal(size=env.action_space.shape)) * env.action_space.high
        obs, _, term, trunc, _ = env.step(a)
        assert np.all(np.isfinite(obs)), f"{env_id}: non-finite observation at step {t}"
        if term or trunc:
            env.reset()


def test_linear_controller_moves_exactly_and_discards_tunnelling() -> None:
    env = _obstruction_scene(config={"controller": "linear"})
    b, r = env.target_block, env.robot
    s0 = env.get_state()
    s0.set(r, "y", 1.5)
    s1, _, _ = env.transition(s0, np.array([0.05, 0.0, 0.0, 0.0, 0.0]))
    assert s1.get(r, "x") - s0.get(r, "x") == pytest.approx(0.05, abs=1e-12)
    assert s1.get(r, "vx_base") == pytest.approx(0.5)  # the commanded average (0.05 per 0.1 s)
    s = env.get_state()
    s.set(b, "vy", -500.0)  # would leave through the table and the floor in one action
    env.set_state(s)
    with pytest.warns(UserWarning, match="discarded"):
        out, *_ = env.step(np.zeros(5))
    assert env.num_physics_reverts == 1
    expected = s.copy()
    expected.set(b, "vy", 0.0)
    assert out.allclose(expected, atol=0.0)


def _replay_record(env_id: str, seed: int, n: int) -> dict[str, list[list[float]]]:
    """A seeded episode with a scripted mix of actions (lots of contacts); states as lists."""
    env = make_object_centric(env_id)
    s, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    hi = env.action_space.high
    actions, states = [], [s.data.tolist()]
    for _ in range(n):
        a = rng.uniform(-hi, hi)
        if env_id.startswith("kinder/DynObstruction"):
            a[1] = -abs(a[1])  # mostly downwards: into the blocks and the table
        s, *_ = env.step(a)
        actions.append(a.tolist())
        states.append(s.data.tolist())
    return {"actions": actions, "states": states}


REPLAY_CODE = """
import json, sys
import numpy as np
from kinder_core import ObjectCentricState, make_object_centric
env_id, start, rec = sys.argv[1], int(sys.argv[2]), json.loads(sys.stdin.read())
env = make_object_centric(env_id)
s, _ = env.reset(seed=99)
env.set_state(ObjectCentricState(s.layout, rec["states"][start]))
out = []
for a in rec["actions"][start:]:
    s, *_ = env.step(np.array(a))
    out.append(s.data.tolist())
print(json.dumps(out))
"""


@pytest.mark.parametrize(
    "env_id",
    [
        "kinder/DynObstruction2D-o2-v0",
        "kinder/DynPushT2D-t1-v0",
        "kinder/DynPushPullHook2D-o5-v0",
        "kinder/DynScoopPour2D-o20-v0",
    ],
)
def test_exact_replay_in_process_and_across_processes(env_id: str) -> None:
    rec = _replay_record(env_id, seed=3, n=120)
    start = 40
    # In this process, after the env did unrelated things.
    env = make_object_centric(env_id)
    env.reset(seed=5)
    for _ in range(10):
        env.step(env.action_space.sample())
    layout = env.get_state().layout
    env.set_state(ObjectCentricState(layout, rec["states"][start]))
    for t, a in enumerate(rec["actions"][start:]):
        s, *_ = env.step(np.array(a))
        np.testing.assert_array_equal(s.data, rec["states"][start + t + 1])
    # In a fresh interpreter.
    out = subprocess.run(
        [sys.executable, "-c", REPLAY_CODE, env_id, str(start)],
        input=json.dumps(rec),
        capture_output=True,
        text=True,
        check=True,
    )
    replay = json.loads(out.stdout)
    np.testing.assert_array_equal(np.array(replay), np.array(rec["states"][start + 1 :]))


def test_scooppour_goal_counts_resting_objects_on_the_right() -> None:
    env = DynScoopPour2DEnv(num_objects=10)
    s, _ = env.reset(seed=0)
    assert env.num_poured(s) == 0 and not env.goal_reached(s)
    smalls = env.smalls
    for i, o in enumerate(smalls[:5]):
        s[o][:2] = (2.0 + 0.2 * i, 0.1)
    assert env.num_poured(s) == 5 and env.goal_reached(s)  # half of 10
    s.set(smalls[0], "vx", 0.02)  # speed² = 4e-4: still moving
    assert env.num_poured(s) == 4 and not env.goal_reached(s)
    s.set(smalls[0], "vx", 0.0)
    s.set(smalls[1], "y", 0.8)  # too high (e.g. still in the scoop)
    assert env.num_poured(s) == 4
    s.set(smalls[1], "y", 0.1)
    s.set(smalls[2], "x", 1.7)  # left of the wall's centre
    assert env.num_poured(s) == 4


def _check_goals_reached(env: Any, data: np.ndarray, layout: Any) -> None:
    """``env.goals_reached`` gives ``goal_reached``'s verdict on every row of ``data`` (a mix
    of both verdicts), in the whole batch and in one-row batches."""
    single = np.array([env.goal_reached(ObjectCentricState(layout, r)) for r in data])
    assert 0.2 < single.mean() < 0.8
    np.testing.assert_array_equal(env.goals_reached(data, layout), single)
    for i in range(0, len(data), 97):
        assert env.goals_reached(data[i : i + 1], layout)[0] == single[i]


def test_obstruction_goals_reached_matches_goal_reached() -> None:
    """The whole-array goal check equals the single one row for row, on blocks placed on,
    beside and tilted over the surface (a third of them on it) and on one-row batches."""
    env = DynObstruction2DEnv(num_obstructions=1)
    rng = np.random.default_rng(1000)
    rows = []
    for seed in range(1000, 1010):
        s, _ = env.reset(seed=seed)
        b, t = s[env.target_block], s[env.target_surface]
        for _ in range(150):
            x = s.copy()
            x.set(env.target_block, "x", t[0] + rng.normal(0, 0.05))
            x.set(env.target_block, "y", t[1] + (t[13] + b[13]) / 2 + rng.normal(0, 0.02))
            x.set(
                env.target_block,
                "theta",
                rng.choice([0.0, rng.normal(0, 0.05), rng.uniform(-3, 3)]),
            )
            rows.append(x.data)
    _check_goals_reached(env, np.array(rows), s.layout)


def test_pushpullhook_goals_reached_matches_goal_reached() -> None:
    """As for DynObstruction2D: blocks placed across, touching and clear of the middle wall,
    at random angles (about half of them in it)."""
    env = DynPushPullHook2DEnv(num_obstructions=5)
    rng = np.random.default_rng(1001)
    wall_y = float(env.middle_wall.poly[:, 1].mean())
    rows = []
    for seed in range(1000, 1005):
        s, _ = env.reset(seed=seed)
        for _ in range(200):
            x = s.copy()
            x.set(env.target_block, "x", rng.uniform(0.2, 3.3))
            x.set(env.target_block, "y", wall_y + rng.normal(0, 0.2))
            x.set(env.target_block, "theta", rng.choice([0.0, rng.uniform(-3, 3)]))
            rows.append(x.data)
    _check_goals_reached(env, np.array(rows), s.layout)


def test_pusht_goal_wraps_angles() -> None:
    """A kept correction: upstream compares raw angles, so a block 0.02 rad from its goal across
    ±π never counts; ours wraps the difference."""
    env = DynPushT2DEnv()
    s, _ = env.reset(seed=0)
    t, g = env.tblock, env.goal_tblock
    s[t][:3] = (2.5, 2.5, math.pi - 0.01)
    s[g][:3] = (2.51, 2.49, -math.pi + 0.01)  # 0.02 rad apart, raw difference ≈ 2π
    assert env.goal_reached(s)
    s.set(g, "theta", -math.pi + 0.2)  # 0.21 rad > 8°
    assert not env.goal_reached(s)
    s[g][:3] = (2.54, 2.5, math.pi - 0.01)  # 0.04 off in x
    assert not env.goal_reached(s)


def test_config_overrides_and_bad_arguments() -> None:
    env = DynObstruction2DEnv(config={"controller": "linear", "action_seconds": 1.0})
    assert env.config.action_seconds == 1.0 and env.scene.settings.substeps == 50
    assert not env.uses_pd and DynObstruction2DEnv().uses_pd
    with pytest.raises(ValueError, match="controller"):
        DynObstruction2DEnv(config={"controller": "exact"})
    with pytest.raises(ValueError, match="multiple of control_hz"):
        DynObstruction2DEnv(config={"sim_hz": 105})
    with pytest.raises(ValueError, match="no field"):
        DynObstruction2DEnv(config={"gravityy": 1.0})
    with pytest.raises(ValueError, match="whole multiple"):
        DynObstruction2DEnv(config={"action_seconds": 0.05, "substep_seconds": 0.02})
    with pytest.raises(ValueError, match="num_obstructions"):
        DynObstruction2DEnv(num_obstructions=-1)
    with pytest.raises(ValueError, match="num_tee"):
        DynPushT2DEnv(num_tee=2)
    with pytest.raises(ValueError, match="num_objects"):
        DynScoopPour2DEnv(num_objects=0)


def test_families_are_constructible_with_any_count() -> None:
    for env in (
        DynObstruction2DEnv(num_obstructions=3),
        DynScoopPour2DEnv(num_objects=3),
    ):
        env.reset(seed=0)
        s2, *_ = env.step(env.action_space.sample())
        assert np.all(np.isfinite(s2.data))
