"""Mappers: input snapshots → clipped env actions, one pure mapping per robot.

A mapper reads an :class:`~kinder_gym.teleop.inputs.InputState` (and, for 3D, the robot's
measured state) and returns a :class:`MapOutput`: the action to apply (``None`` pauses the robot:
no step, nothing recorded) and the episode events the bindings produced. The action is always
inside the env's action bounds.

2D robots (:class:`Teleop2DMapper`), chosen by the robot object's type:

* ``crv_robot`` (Kinematic2D, the vacuum robot): ``[dx, dy, dθ, darm, vacuum]``.
* ``kin_robot`` (Dynamic2D, the two-finger gripper): ``[dx, dy, dθ, darm, dgripper]``.
* ``dot_robot`` (DynPushT2D, a pusher disc): ``[dx, dy]``.

Every device first becomes a device-independent :class:`Intent2D` (:func:`intent_2d`, the
bindings), then :func:`action_2d` scales it to the bounds: an intent of 1 is the largest step
``max(|low|, |high|)`` of that dimension and an intent of 0 is **no motion** (not the bounds'
midpoint, an upstream bug for asymmetric bounds), then clipped to the bounds.

**Vacuum and gripper toggle** on every device and every 2D family: one press of the grip binding
(Space, the pad's Cross/A button) turns the vacuum on / starts closing the fingers, the next press
turns it off / opens them. While "on", the vacuum action is 1 and the finger action is the
largest closing step; while "off", 0 and the largest opening step (so fingers open fully and
stay open). Deviation from upstream, where the vacuum was hold-to-activate although documented
as a toggle and Dynamic2D fingers could not be reached from a pad.

Default 2D bindings (also shown in the window, :data:`BINDINGS_2D`): keyboard WASD or arrows
translate (up = +y), Q/E rotate counter-clockwise/clockwise, R/F extend/retract the arm, Space
toggles grip, Shift held = fine motion (×0.3), Enter saves, Backspace discards, Ctrl+R restarts
the seed, Esc quits; on-screen sticks (mouse): right stick translates, left stick x rotates and y
moves the arm; gamepad (SDL GameController names; the paper's DualSense mapping): right stick
translates, left stick rotates (right = clockwise), Cross/A toggles grip, D-pad up/down extends/
retracts the arm, Triangle/Y saves, Square/X discards, Circle/B restarts the seed. Stick
dead zone 0.1, rescaled so motion starts at 0 past it.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Protocol

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import ObjectCentricEnv
from kinder_gym.teleop.inputs import InputState

FloatArray = NDArray[np.float64]

#: Dead zone of gamepad sticks (fraction of full deflection).
DEADZONE = 0.1
#: Speed factor while Shift is held.
FINE = 0.3

BINDINGS_2D: tuple[tuple[str, str], ...] = (
    ("WASD / arrows", "translate"),
    ("Q / E", "rotate ccw / cw"),
    ("R / F", "arm extend / retract"),
    ("Space", "grip on / off (toggle)"),
    ("Shift (held)", "fine motion"),
    ("Enter", "save episode"),
    ("Backspace", "discard episode"),
    ("Ctrl+R", "restart this seed"),
    ("Esc", "quit"),
    ("mouse sticks", "R: translate, L: rotate/arm"),
    ("pad R / L stick", "translate / rotate"),
    ("pad Cross, D-pad", "grip toggle, arm"),
    ("pad △ / □ / ○", "save / discard / restart"),
)


@dataclasses.dataclass(frozen=True)
class MapOutput:
    """What a mapper made of one input snapshot."""

    action: FloatArray | None
    """The action to apply, inside the bounds; ``None`` pauses (deadman released)."""
    events: frozenset[str] = frozenset()
    """Episode events (``save``, ``discard``, ``reset``, ``quit``)."""
    info: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Extra status for the display (targets, IK failures, grip state)."""


class Mapper(Protocol):
    """The interface the teleop loop drives (2D and 3D mappers)."""

    def reset(self, env: gymnasium.Env[Any, Any]) -> None:
        """A new episode started: clear toggles and re-capture references."""

    def __call__(self, state: InputState, env: gymnasium.Env[Any, Any]) -> MapOutput:
        """The action (or pause) and events for one snapshot."""


def deadzone(value: float, zone: float = DEADZONE) -> float:
    """``value`` in [−1, 1] with the central ``zone`` removed and the rest rescaled to [−1, 1]."""
    magnitude = abs(value)
    if magnitude <= zone:
        return 0.0
    return float(np.sign(value)) * min(1.0, (magnitude - zone) / (1.0 - zone))


def _clip1(value: float) -> float:
    return max(-1.0, min(1.0, value))


def _key_axis(held: frozenset[str], plus: tuple[str, ...], minus: tuple[str, ...]) -> float:
    return float(any(k in held for k in plus)) - float(any(k in held for k in minus))


def pad_events(s: InputState) -> set[str]:
    """Episode events from gamepad buttons (Triangle/Y save, Square/X discard, Circle/B reset)
    and web event buttons (``event_<name>``)."""
    events = set()
    for button, event in (("pad_y", "save"), ("pad_x", "discard"), ("pad_b", "reset")):
        if button in s.pressed:
            events.add(event)
    for name in ("save", "discard", "reset", "quit"):
        if f"event_{name}" in s.pressed:
            events.add(name)
    return events


def keyboard_events(s: InputState) -> set[str]:
    """Episode events from keys: Enter save, Backspace discard, Ctrl+R reset, Esc quit."""
    events = set()
    ctrl = "left ctrl" in s.buttons or "right ctrl" in s.buttons
    if "return" in s.pressed or "enter" in s.pressed:
        events.add("save")
    if "backspace" in s.pressed:
        events.add("discard")
    if ctrl and "r" in s.pressed:
        events.add("reset")
    if "escape" in s.pressed or "window_close" in s.pressed:
        events.add("quit")
    return events


@dataclasses.dataclass(frozen=True)
class Intent2D:
    """Device-independent 2D command: each motion in [−1, 1] (1 = the largest step)."""

    move_x: float = 0.0
    move_y: float = 0.0
    rotate: float = 0.0
    arm: float = 0.0
    toggle_grip: bool = False
    events: frozenset[str] = frozenset()


def intent_2d(s: InputState) -> Intent2D:
    """Apply the 2D bindings (module docstring) to a snapshot."""
    held = s.buttons
    ctrl = "left ctrl" in held or "right ctrl" in held
    gain = FINE if ("left shift" in held or "right shift" in held) else 1.0
    move_x = gain * _key_axis(held, ("d", "right"), ("a", "left"))
    move_y = gain * _key_axis(held, ("w", "up"), ("s", "down"))
    rotate = gain * _key_axis(held, ("q",), ("e",))
    arm = gain * _key_axis(held, () if ctrl else ("r",), ("f",))
    # On-screen mouse sticks.
    move_x += s.axis("mouse_rx")
    move_y += s.axis("mouse_ry")
    rotate -= s.axis("mouse_lx")
    arm += s.axis("mouse_ly")
    # Gamepad: right stick translates, left stick rotates, D-pad moves the arm.
    move_x += deadzone(s.axis("pad_rx"))
    move_y += deadzone(s.axis("pad_ry"))
    rotate -= deadzone(s.axis("pad_lx"))
    arm += _key_axis(held, ("pad_up",), ("pad_down",))
    toggle = "space" in s.pressed or "pad_a" in s.pressed
    return Intent2D(
        move_x=_clip1(move_x),
        move_y=_clip1(move_y),
        rotate=_clip1(rotate),
        arm=_clip1(arm),
        toggle_grip=toggle,
        events=frozenset(keyboard_events(s) | pad_events(s)),
    )


ROBOT_KINDS_2D = {"crv_robot": "vacuum", "kin_robot": "gripper", "dot_robot": "dot"}


def action_2d(
    intent: Intent2D, grip_on: bool, kind: str, low: FloatArray, high: FloatArray
) -> FloatArray:
    """The env action for ``intent`` (see the module docstring), clipped to ``[low, high]``."""
    scale = np.maximum(np.abs(low), np.abs(high))
    if kind == "dot":
        raw = np.array([intent.move_x, intent.move_y]) * scale[:2]
    elif kind in ("vacuum", "gripper"):
        motion = np.array([intent.move_x, intent.move_y, intent.rotate, intent.arm]) * scale[:4]
        on, off = (1.0, 0.0) if kind == "vacuum" else (-scale[4], scale[4])  # fingers: + opens
        grip = on if grip_on else off
        raw = np.array([*motion, grip])
    else:
        raise ValueError(f"Unknown 2D robot kind {kind!r}; expected vacuum, gripper or dot")
    if raw.shape != low.shape:
        raise ValueError(
            f"A {kind} robot maps to {raw.shape[0]} action dims, the env has {low.shape[0]}"
        )
    return np.asarray(np.clip(raw, low, high), dtype=np.float64)


def robot_type_name(env: gymnasium.Env[Any, Any]) -> str:
    """The type name of the env's object named ``robot`` (resets a fresh env with seed 0 to see
    its objects)."""
    model = env.unwrapped
    if not isinstance(model, ObjectCentricEnv):
        raise TypeError(f"Teleoperation needs a KinDER env, got {type(model).__name__}")
    try:
        state = model.get_state()
    except RuntimeError:
        env.reset(seed=0)
        state = model.get_state()
    for obj in state:
        if obj.name == "robot":
            return str(obj.type.name)
    raise ValueError(f"{type(model).__name__} has no object named 'robot'")


class Teleop2DMapper:
    """The mapper of every 2D family (module docstring); holds only the grip toggle."""

    def __init__(self, env: gymnasium.Env[Any, Any]) -> None:
        robot = robot_type_name(env)
        if robot not in ROBOT_KINDS_2D:
            raise ValueError(
                f"No 2D teleop mapping for robot type {robot!r}; expected one of "
                f"{sorted(ROBOT_KINDS_2D)}"
            )
        if not isinstance(env.action_space, spaces.Box):
            raise TypeError("Teleoperation needs a Box action space")
        self.kind = ROBOT_KINDS_2D[robot]
        self.low = np.asarray(env.action_space.low, dtype=np.float64)
        self.high = np.asarray(env.action_space.high, dtype=np.float64)
        self.grip_on = False

    def reset(self, env: gymnasium.Env[Any, Any]) -> None:
        self.grip_on = False

    def __call__(self, state: InputState, env: gymnasium.Env[Any, Any]) -> MapOutput:
        intent = intent_2d(state)
        if intent.toggle_grip and self.kind != "dot":
            self.grip_on = not self.grip_on
        action = action_2d(intent, self.grip_on, self.kind, self.low, self.high)
        return MapOutput(
            action if state.enabled else None,
            intent.events,
            {"grip": self.grip_on, "kind": self.kind},
        )
