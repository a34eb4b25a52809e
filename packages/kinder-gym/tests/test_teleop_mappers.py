"""Mapper unit tests for every 2D robot (pure: no pygame, no window)."""

from __future__ import annotations

import numpy as np
import pytest

import kinder_core
from kinder_gym.teleop.inputs import InputState
from kinder_gym.teleop.mappers import Intent2D, Teleop2DMapper, action_2d, deadzone, intent_2d

IDS = {
    "vacuum": "kinder/Motion2D-p0-v0",
    "gripper": "kinder/DynObstruction2D-o0-v0",
    "dot": "kinder/DynPushT2D-t1-v0",
}


def snap(buttons: set[str] = frozenset(), pressed: set[str] = frozenset(), **axes: float):  # type: ignore[no-untyped-def]
    return InputState(
        t=0.0, source="test", buttons=frozenset(buttons), pressed=frozenset(pressed), axes=axes
    )


@pytest.fixture(scope="module", params=sorted(IDS))
def env_and_kind(request):  # type: ignore[no-untyped-def]
    env = kinder_core.make(IDS[request.param])
    env.reset(seed=0)
    yield env, request.param
    env.close()


def test_zero_input_is_no_motion(env_and_kind) -> None:  # type: ignore[no-untyped-def]
    env, kind = env_and_kind
    mapper = Teleop2DMapper(env)
    assert mapper.kind == kind
    action = mapper(snap(), env).action
    assert action is not None
    assert np.all(action[: min(4, len(action))] == 0.0)
    assert env.action_space.contains(action.astype(env.action_space.dtype))


def test_full_input_inside_bounds_and_deadman(env_and_kind) -> None:  # type: ignore[no-untyped-def]
    env, _ = env_and_kind
    mapper = Teleop2DMapper(env)
    held = {"w", "d", "q", "r", "up"}
    action = mapper(snap(held, pad_rx=1.0, pad_ry=1.0, mouse_ly=1.0), env).action
    assert action is not None
    low, high = env.action_space.low, env.action_space.high
    assert np.all(action >= low - 1e-9)
    assert np.all(action <= high + 1e-9)
    assert action[0] == pytest.approx(high[0])
    assert action[1] == pytest.approx(high[1])
    paused = mapper(
        InputState(t=0.0, source="test", enabled=False, buttons=frozenset(held)), env
    ).action
    assert paused is None


def test_grip_toggles_the_same_on_every_device(env_and_kind) -> None:  # type: ignore[no-untyped-def]
    env, kind = env_and_kind
    if kind == "dot":  # the pusher has no grip: the grip binding changes nothing
        mapper = Teleop2DMapper(env)
        idle = mapper(snap(), env).action
        pressed = mapper(snap({"space"}, {"space"}), env).action
        assert idle is not None and pressed is not None
        assert np.array_equal(idle, pressed) and mapper.grip_on is False
        return
    for button in ("space", "pad_a"):
        mapper = Teleop2DMapper(env)
        a0 = mapper(snap(), env).action
        a1 = mapper(snap({button}, {button}), env).action  # press: on
        a2 = mapper(snap({button}), env).action  # still held: stays on
        a3 = mapper(snap(set(), set()), env).action  # released: stays on (toggle)
        a4 = mapper(snap({button}, {button}), env).action  # pressed again: off
        assert a0 is not None and a1 is not None and a2 is not None
        assert a3 is not None and a4 is not None
        off, on = a0[4], a1[4]
        if kind == "vacuum":
            assert (off, on) == (0.0, 1.0)
        else:
            assert off > 0 > on  # fingers open while off, close while on
        assert a2[4] == on and a3[4] == on and a4[4] == off
        mapper.reset(env)
        assert mapper.grip_on is False


def test_directions_and_rescaling() -> None:
    low = np.array([-0.05, -0.05, -0.2, -0.1, 0.0])
    high = np.array([0.05, 0.05, 0.2, 0.1, 1.0])
    a = action_2d(
        Intent2D(move_x=1.0, move_y=-0.5, rotate=1.0, arm=-1.0), False, "vacuum", low, high
    )
    np.testing.assert_allclose(a, [0.05, -0.025, 0.2, -0.1, 0.0])
    # Asymmetric bounds: 0 stays 0 (not the midpoint), 1 is the largest step, then clipped.
    low2, high2 = np.array([-0.02, 0.0]), np.array([0.06, 0.01])
    a2 = action_2d(Intent2D(move_x=0.0, move_y=0.0), False, "dot", low2, high2)
    np.testing.assert_allclose(a2, [0.0, 0.0])
    a3 = action_2d(Intent2D(move_x=-1.0, move_y=1.0), False, "dot", low2, high2)
    np.testing.assert_allclose(a3, [-0.02, 0.01])
    with pytest.raises(ValueError, match="action dims"):
        action_2d(Intent2D(), False, "dot", low, high)


def test_bindings() -> None:
    assert intent_2d(snap({"w"})).move_y == 1.0
    assert intent_2d(snap({"s", "left shift"})).move_y == pytest.approx(-0.3)
    assert intent_2d(snap({"q"})).rotate == 1.0
    assert intent_2d(snap({"f"})).arm == -1.0
    assert intent_2d(snap({"left ctrl", "r"}, {"r"})).events == {"reset"}
    assert intent_2d(snap({"left ctrl", "r"}, {"r"})).arm == 0.0
    assert intent_2d(snap({"return"}, {"return"})).events == {"save"}
    assert intent_2d(snap({"pad_y"}, {"pad_y"})).events == {"save"}
    assert intent_2d(snap({"pad_x"}, {"pad_x"})).events == {"discard"}
    assert intent_2d(snap(set(), {"window_close"})).events == {"quit"}
    # Pad: right stick translates, left stick rotates (right = clockwise), D-pad moves the arm.
    i = intent_2d(snap({"pad_up"}, pad_rx=0.05, pad_ry=-1.0, pad_lx=1.0))
    assert (i.move_x, i.move_y, i.rotate, i.arm) == (0.0, -1.0, -1.0, 1.0)
    assert deadzone(0.1) == 0.0
    assert deadzone(0.55) == pytest.approx(0.5)
    assert deadzone(-1.0) == -1.0
