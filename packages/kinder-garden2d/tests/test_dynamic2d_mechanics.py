"""Dynamic2D mechanics: grasp, carry and release; pushing; grasp rules; settling; physics
safety; exact replay; goal predicates."""

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
from kinder_garden2d.dynamic2d.dyn_pusht2d import DynPushT2DEnv
from kinder_garden2d.dynamic2d.dyn_scooppour2d import DynScoopPour2DEnv
from kinder_garden2d.dynamic2d.geometry import WorldShape, penetration, place
from kinder_garden2d.dynamic2d.physics import StaticBox, shape_spec

TABLE = 0.1


def _obstruction_scene(
    block_x: float = 1.5, width: float = 0.2, height: float = 0.3
) -> DynObstruction2DEnv:
    """DynObstruction2D-o0 with the block at ``block_x`` and the robot pointing down above it,
    fingertips 0.1 below the block's top, fingers open."""
    env = DynObstruction2DEnv(num_obstructions=0)
    s, _ = env.reset(seed=0)
    b = env.target_block
    s.set(b, "x", block_x)
    s.set(b, "y", TABLE + height / 2)
    s.set(b, "theta", 0.0)
    s.set(b, "width", width)
    s.set(b, "height", height)
    s.set(env.target_surface, "x", 2.8)
    r = env.robot
    reach = s.get(r, "arm_joint") + s.get(r, "gripper_base_width") / 2 + s.get(r, "finger_width")
    s.set(r, "x", block_x + 0.02)  # off-centre: one finger touches first
    s.set(r, "y", TABLE + height - 0.1 + reach)
    s.set(r, "theta", -math.pi / 2)
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


def test_grasp_carry_release() -> None:
    env = _obstruction_scene()
    b, r = env.target_block, env.robot
    s = _act(env, 6, dgripper=-0.02)  # 0.32 → 0.20 at most; the block (0.2) is held earlier
    assert s.get(b, "held") == 1.0
    gap = s.get(r, "finger_gap")
    assert gap > 0.2 + 0.06 - 0.03  # the fingers stopped on the block
    s = _act(env, 3, dgripper=-0.02)
    assert s.get(r, "finger_gap") == gap  # a held object keeps the fingers where they are
    # Carry: the block moves rigidly with the gripper.
    rel = s[b][:2] - s[r][:2]
    s = _act(env, 8, dy=0.05)
    s = _act(env, 6, dx=0.05)
    assert s.get(b, "held") == 1.0
    np.testing.assert_allclose(s[b][:2] - s[r][:2], rel, atol=1e-9)
    assert s.get(b, "y") > TABLE + 0.15 + 0.35
    assert s.get(b, "vx") == pytest.approx(0.5)  # 0.05 per 0.1 s
    # Release while moving: the block leaves the opening fingers with the gripper's velocity.
    s = _act(env, 1, dx=0.05, dgripper=0.02)
    assert s.get(b, "held") == 0.0
    assert s.get(b, "vx") == pytest.approx(0.5, abs=0.02)
    assert s.get(b, "vy") < -0.5  # falling
    s = _act(env, 20)
    assert s.get(b, "y") == pytest.approx(TABLE + 0.15, abs=0.01)  # back on the table
    assert abs(s.get(b, "vx")) < 1e-2 and abs(s.get(b, "vy")) < 1e-2


def test_push_without_grasp() -> None:
    env = _obstruction_scene()
    b, r = env.target_block, env.robot
    s = env.get_state()
    # The base (radius 0.24) at the block's left, at block height, arm pointing up.
    s.set(r, "theta", math.pi / 2)
    s.set(r, "x", 1.5 - 0.1 - 0.24 - 0.02)
    s.set(r, "y", TABLE + 0.24 + 0.02)
    env.set_state(s)
    x0 = s.get(b, "x")
    s = _act(env, 10, dx=0.05)
    assert s.get(b, "x") > x0 + 0.3
    assert s.get(b, "held") == 0.0
    assert s.get(r, "x") == pytest.approx(1.5 - 0.36 + 0.5)  # the robot was never blocked


def test_static_contact_stops_the_robot() -> None:
    env = _obstruction_scene()
    r = env.robot
    s = env.get_state()
    y0 = s.get(r, "y")
    for _ in range(30):
        s, *_ = env.step(np.array([0.0, -0.05, 0.0, 0.0, 0.0]))
    # Fingertips (0.47 below the base) stop above the table top; nothing went through it.
    assert s.get(r, "y") - 0.47 >= TABLE - 1e-9
    assert s.get(r, "y") < y0
    assert s.get(r, "vy_base") == 0.0


def test_two_objects_between_the_fingers_abort_the_grasp() -> None:
    env = DynObstruction2DEnv(num_obstructions=1)
    s, _ = env.reset(seed=0)
    a, b, r = env.target_block, env.obstructions[0], env.robot
    for obj, x in ((a, 1.45), (b, 1.55)):
        s[obj][:3] = (x, TABLE + 0.15, 0.0)
        s.set(obj, "width", 0.08)
        s.set(obj, "height", 0.3)
    s.set(env.target_surface, "x", 2.8)
    s[r][:3] = (1.5, TABLE + 0.3 - 0.1 + 0.47, -math.pi / 2)
    s.set(r, "finger_gap", 0.245)  # finger faces 0.0025 from the blocks' outer sides
    env.set_state(s)
    gaps = [s.get(r, "finger_gap")]
    for _ in range(8):
        s, *_ = env.step(np.array([0.0, 0.0, 0.0, 0.0, -0.02]))
        gaps.append(s.get(r, "finger_gap"))
        assert s.get(a, "held") == 0.0 and s.get(b, "held") == 0.0
    assert max(np.diff(gaps)) > 0  # the fingers opened after touching both blocks


def test_small_objects_are_never_grasped() -> None:
    env = DynScoopPour2DEnv(num_objects=2)
    s, _ = env.reset(seed=0)
    r = env.robot
    sq = env.squares[0]
    s[sq][:6] = (2.5, 0.044, 0.0, 0.0, 0.0, 0.0)
    reach = s.get(r, "arm_joint") + s.get(r, "gripper_base_width") / 2 + s.get(r, "finger_width")
    s[r][:3] = (2.5, 0.03 + reach, -math.pi / 2)
    env.set_state(s)
    for _ in range(15):
        s, *_ = env.step(np.array([0.0, 0.0, 0.0, 0.0, -0.015]))
        assert s.get(sq, "held") == 0.0


def test_scoop_handle_is_grasped_and_lifted() -> None:
    env = DynScoopPour2DEnv(num_objects=2)
    s, _ = env.reset(seed=0)
    r, h = env.robot, env.hook
    hx, hy = s.get(h, "x"), s.get(h, "y")
    reach = s.get(r, "arm_joint") + s.get(r, "gripper_base_width") / 2 + s.get(r, "finger_width")
    # Fingers around the top of the upright handle (x ∈ [hx − 0.05, hx]).
    s[r][:3] = (hx - 0.025, hy + 0.45 + reach, -math.pi / 2)
    env.set_state(s)
    for _ in range(12):
        s, *_ = env.step(np.array([0.0, 0.0, 0.0, 0.0, -0.015]))
    assert s.get(h, "held") == 1.0
    s = _act(env, 10, dy=0.03)
    assert s.get(h, "y") > hy + 0.25


@pytest.mark.parametrize(
    "env_id",
    [
        "kinder/DynObstruction2D-o3-v0",
        "kinder/DynPushT2D-t1-v0",
        "kinder/DynPushPullHook2D-o5-v0",
        "kinder/DynScoopPour2D-o50-v0",
    ],
)
def test_settled_resets_have_no_overlaps(env_id: str) -> None:
    env = make_object_centric(env_id)
    u = env.unwrapped
    for seed in range(3):
        s, _ = env.reset(seed=seed)
        shapes = []
        for o in u.scene.objects:
            names, builder = shape_spec(o.type)
            f = s[o]
            shapes.append(place(builder(*(s.get(o, n) for n in names)), f[0], f[1], f[2]))
        statics = [place_static(sb) for sb in u.scene.statics if sb.z == 100.0]
        worst = max(
            [penetration(a, b) for i, a in enumerate(shapes) for b in shapes[i + 1 :]]
            + [penetration(a, w) for a in shapes for w in statics]
            + [-1.0]
        )
        assert worst < 0.005, f"{env_id} seed {seed}: objects overlap by {worst:.4f}"
        assert np.all(s.data[u.scene.pose_idx[:, 3:]] == 0.0)  # at rest


def place_static(sb: StaticBox) -> WorldShape:
    return WorldShape((sb.poly,))


@pytest.mark.parametrize(
    ("env_id", "steps"),
    [
        ("kinder/DynObstruction2D-o3-v0", 3000),
        ("kinder/DynPushT2D-t1-v0", 3000),
        ("kinder/DynPushPullHook2D-o5-v0", 3000),
        ("kinder/DynScoopPour2D-o20-v0", 2000),
    ],
)
def test_random_steps_stay_finite_and_in_the_world(env_id: str, steps: int) -> None:
    env = make(env_id)
    box = env.get_wrapper_attr("box")
    u = env.unwrapped
    env.reset(seed=1)
    env.action_space.seed(1)
    rng = np.random.default_rng(1)
    for t in range(steps):
        # Mostly random; sometimes a burst of one repeated extreme action (drives into walls).
        if rng.uniform() < 0.7:
            a = env.action_space.sample()
        else:
            a = np.sign(rng.normal(size=env.action_space.shape)) * env.action_space.high
        obs, _, term, trunc, _ = env.step(a)
        assert np.all(np.isfinite(obs)), f"{env_id}: non-finite observation at step {t}"
        assert box.contains(obs), f"{env_id}: observation outside the Box at step {t}"
        if term or trunc:
            env.reset()
    assert u.num_physics_reverts <= steps // 100


def test_tunnelling_is_detected_and_discarded() -> None:
    env = _obstruction_scene()
    b = env.target_block
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


def test_pusht_goal_wraps_angles() -> None:
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
    env = DynObstruction2DEnv(config={"action_seconds": 1.0})
    assert env.config.action_seconds == 1.0 and env.scene.settings.substeps == 50
    with pytest.raises(ValueError, match="no field"):
        DynObstruction2DEnv(config={"gravityy": 1.0})
    with pytest.raises(ValueError, match="whole multiple"):
        DynObstruction2DEnv(config={"action_seconds": 0.05, "substep_seconds": 0.02})
    with pytest.raises(ValueError, match="num_obstructions"):
        DynObstruction2DEnv(num_obstructions=-1)
    with pytest.raises(ValueError, match="num_tee"):
        DynPushT2DEnv(num_tee=2)
    with pytest.raises(ValueError, match="do not fit"):
        DynScoopPour2DEnv(num_objects=100)


def test_families_are_constructible_with_any_count() -> None:
    for env in (
        DynObstruction2DEnv(num_obstructions=5),
        DynScoopPour2DEnv(num_objects=3),
    ):
        env.reset(seed=0)
        s2, *_ = env.step(env.action_space.sample())
        assert np.all(np.isfinite(s2.data))
