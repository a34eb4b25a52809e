"""The 3D mapper: bindings, clutch frames, rate limits, IK and the action bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

import kinder_core
from kinder_gym.teleop.inputs import InputState, Pose
from kinder_gym.teleop.mapper3d import (
    Limits,
    TidyBotTeleop,
    ee_pose_in_base,
    webxr_to_robot,
)


@pytest.fixture(scope="module")
def env():  # type: ignore[no-untyped-def]
    e = kinder_core.make("kinder/BaseMotion3D-v0")
    e.reset(seed=0)
    yield e
    e.close()


def keys(*held: str, pressed: tuple[str, ...] = ()) -> InputState:
    return InputState(t=0.0, source="keyboard", buttons=frozenset(held), pressed=frozenset(pressed))


def grab(channel: str, p: tuple[float, float, float], n: int = 1, **kw: object) -> InputState:
    return InputState(
        t=0.0,
        source="web",
        engaged=frozenset({channel}),
        poses={channel: Pose(p, grab=n)},
        **kw,  # type: ignore[arg-type]
    )


def test_webxr_frame_conversion() -> None:
    p, q = webxr_to_robot(Pose((0.1, 0.2, -0.3), (0.0, math.sin(0.25), 0.0, math.cos(0.25))))
    np.testing.assert_allclose(p, [0.3, -0.1, 0.2])  # forward, right (−y), up
    np.testing.assert_allclose(q, [0.0, 0.0, math.sin(0.25), math.cos(0.25)])  # yaw left


def test_zero_input_holds_and_actions_stay_in_bounds(env) -> None:  # type: ignore[no-untyped-def]
    env.reset(seed=0)
    mapper = TidyBotTeleop(env, hz=10)
    action = mapper(keys(), env).action
    assert action is not None
    np.testing.assert_allclose(action[:10], 0.0, atol=1e-6)
    assert action[10] == 1.0  # Kinematic3D: +1 = open
    every = keys("w", "a", "q", "i", "j", "u", "up", "left", "x")
    for _ in range(5):
        action = mapper(every, env).action
        assert action is not None
        assert np.all(action >= env.action_space.low) and np.all(action <= env.action_space.high)
        env.step(action)
    assert mapper(keys(pressed=("space",)), env).action[10] == -1.0  # type: ignore[index]


def test_keyboard_drives_base_in_its_frame_and_hand_in_base_frame(env) -> None:  # type: ignore[no-untyped-def]
    env.reset(seed=0)
    mapper = TidyBotTeleop(env, hz=10, limits=Limits(base_speed=0.5, ee_speed=0.2))
    base0, arm0 = mapper.measured(env)
    p0, _ = ee_pose_in_base(arm0)
    for _ in range(4):
        env.step(mapper(keys("w"), env).action)
    base1, _ = mapper.measured(env)
    np.testing.assert_allclose(base1 - base0, [0.2, 0.0, 0.0], atol=1e-9)
    for _ in range(4):
        env.step(mapper(keys("u"), env).action)
    _, arm2 = mapper.measured(env)
    p2, _ = ee_pose_in_base(arm2)
    np.testing.assert_allclose(p2 - p0, [0.0, 0.0, 0.08], atol=3e-3)
    for _ in range(3):
        env.step(mapper(keys("q"), env).action)
    assert mapper.measured(env)[0][2] == pytest.approx(0.45)  # 1.5 rad/s × 0.3 s


def test_clutch_moves_relative_to_the_grab_and_release_holds(env) -> None:  # type: ignore[no-untyped-def]
    env.reset(seed=0)
    mapper = TidyBotTeleop(env, hz=10)
    _, arm0 = mapper.measured(env)
    p0, _ = ee_pose_in_base(arm0)
    # The phone moves 5 cm forward (WebXR −z): the hand target moves +5 cm in x.
    for _ in range(5):
        out = mapper(grab("arm", (0.0, 0.0, -0.05)), env)
        env.step(out.action)
    np.testing.assert_allclose(mapper.ee_p - p0, [0.05, 0.0, 0.0], atol=1e-12)
    p1, _ = ee_pose_in_base(mapper.measured(env)[1])
    np.testing.assert_allclose(p1 - p0, [0.05, 0.0, 0.0], atol=3e-3)
    # Deadman released: paused (None) and the target snaps to the measured hand.
    released = mapper(InputState(t=0.0, source="web", enabled=False), env)
    assert released.action is None
    np.testing.assert_allclose(mapper.ee_p, p1, atol=1e-12)
    # A new grab starts from the robot's pose: no jump ...
    mapper(grab("arm", (0.0, 0.0, 0.0), n=2), env)
    np.testing.assert_allclose(mapper.ee_p, p1, atol=1e-12)
    # ... and its motion is rate-limited: 0.3 m/s × 0.1 s per tick towards +5 cm.
    out = mapper(grab("arm", (0.0, 0.0, -0.05), n=2), env)
    np.testing.assert_allclose(mapper.ee_p - p1, [0.03, 0.0, 0.0], atol=1e-12)
    assert out.action is not None and np.max(np.abs(out.action[3:10])) <= 0.4
    out = mapper(grab("arm", (0.0, 0.0, -0.05), n=2), env)
    np.testing.assert_allclose(mapper.ee_p - p1, [0.05, 0.0, 0.0], atol=1e-12)
    # An unreachable hand target: the arm keeps its last reachable goal and says so.
    env.reset(seed=0)
    mapper.reset(env)
    base, arm = mapper.measured(env)
    mapper.ee_p = np.array([3.0, 0.0, 0.5])
    action = mapper.action(base, arm)
    assert mapper._ik_ok is False
    np.testing.assert_allclose(action[3:10], 0.0, atol=1e-12)


def test_base_clutch_turns_with_the_device_and_dynamic_gripper() -> None:
    env = kinder_core.make("kinder/BaseMotion3D-v0")
    env.reset(seed=0)
    mapper = TidyBotTeleop(env, hz=10, limits=Limits(base_yaw_speed=10.0))
    yaw = 0.3
    q = (0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2))  # about WebXR +y = robot +z
    s = InputState(
        t=0.0, source="web", engaged=frozenset({"base"}), poses={"base": Pose((0, 0, 0), q, 1)}
    )
    env.step(mapper(s, env).action)
    assert mapper.measured(env)[0][2] == pytest.approx(yaw)
    env.close()
    dyn = kinder_core.make("kinder/Shelf3D-o1-v0")
    dyn.reset(seed=0)
    m = TidyBotTeleop(dyn, hz=10)
    assert m.family == "dynamic"
    out = m(
        InputState(t=0.0, source="web", engaged=frozenset({"gripper"}), scalars={"gripper": 0.7}),
        dyn,
    )
    assert out.action is not None and out.action[10] == pytest.approx(0.7)
    assert np.all(np.abs(out.action[:10]) <= 0.1)
    dyn.close()
