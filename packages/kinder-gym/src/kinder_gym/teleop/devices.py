"""Devices: turn an event stream into :class:`~kinder_gym.teleop.inputs.InputState` snapshots.

:class:`PygameInput` is the keyboard, mouse and gamepad device of the pygame windows. It builds
its state **from the event stream only** (``KEYDOWN``/``KEYUP``, ``MOUSE*``, ``CONTROLLER*``),
never by polling ``pygame.key.get_pressed()``, ``pygame.mouse.get_pos()`` or joystick axes: posted
events do not update those, so a polling device cannot be driven by a test, while this one is
driven by ``pygame.event.post`` exactly as by a person.

Gamepads go through SDL's GameController API (``pygame._sdl2.controller``): buttons and axes have
the same names on every platform and for every pad in SDL's controller database (DualSense,
DualShock, Xbox, Switch Pro, …; ``SDL_GAMECONTROLLERCONFIG`` adds others). Raw joysticks SDL does
not know as game controllers are not supported (their button and axis indices differ per driver
and platform, the upstream bug this avoids).

:class:`ScriptInput` replays a list of snapshots (tests, benchmarks).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from kinder_gym.teleop.inputs import InputState

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
import pygame

_AXES = {
    pygame.CONTROLLER_AXIS_LEFTX: ("pad_lx", 1.0),
    pygame.CONTROLLER_AXIS_LEFTY: ("pad_ly", -1.0),  # SDL's y points down; ours points up
    pygame.CONTROLLER_AXIS_RIGHTX: ("pad_rx", 1.0),
    pygame.CONTROLLER_AXIS_RIGHTY: ("pad_ry", -1.0),
    pygame.CONTROLLER_AXIS_TRIGGERLEFT: ("pad_lt", 1.0),
    pygame.CONTROLLER_AXIS_TRIGGERRIGHT: ("pad_rt", 1.0),
}
_BUTTONS = {
    pygame.CONTROLLER_BUTTON_A: "pad_a",  # bottom face button (DualSense Cross)
    pygame.CONTROLLER_BUTTON_B: "pad_b",  # right (Circle)
    pygame.CONTROLLER_BUTTON_X: "pad_x",  # left (Square)
    pygame.CONTROLLER_BUTTON_Y: "pad_y",  # top (Triangle)
    pygame.CONTROLLER_BUTTON_BACK: "pad_back",  # Create / Share
    pygame.CONTROLLER_BUTTON_GUIDE: "pad_guide",
    pygame.CONTROLLER_BUTTON_START: "pad_start",  # Options
    pygame.CONTROLLER_BUTTON_LEFTSTICK: "pad_l3",
    pygame.CONTROLLER_BUTTON_RIGHTSTICK: "pad_r3",
    pygame.CONTROLLER_BUTTON_LEFTSHOULDER: "pad_l1",
    pygame.CONTROLLER_BUTTON_RIGHTSHOULDER: "pad_r1",
    pygame.CONTROLLER_BUTTON_DPAD_UP: "pad_up",
    pygame.CONTROLLER_BUTTON_DPAD_DOWN: "pad_down",
    pygame.CONTROLLER_BUTTON_DPAD_LEFT: "pad_left",
    pygame.CONTROLLER_BUTTON_DPAD_RIGHT: "pad_right",
}


class PygameInput:
    """Keyboard, mouse (on-screen sticks) and SDL game controllers, from pygame events.

    Args:
        sticks: On-screen sticks for the mouse: name → ``(centre_x, centre_y, radius)`` in window
            pixels. Dragging with the left button inside a stick sets axes ``mouse_<name>x`` and
            ``mouse_<name>y`` (offset / radius, clipped to [−1, 1], y up); releasing recentres it.
        open_controllers: Open the game controllers SDL already knows at construction (a real
            window does; tests that only post events do not need it).
    """

    def __init__(
        self,
        sticks: Mapping[str, tuple[float, float, float]] | None = None,
        open_controllers: bool = True,
    ) -> None:
        self.sticks = dict(sticks or {})
        self._held: set[str] = set()
        self._pressed: set[str] = set()
        self._axes: dict[str, float] = {}
        self._drag: str | None = None
        self._controllers: dict[int, Any] = {}
        self.gamepad_seen = False
        if open_controllers:
            from pygame._sdl2 import controller

            controller.init()
            for index in range(controller.get_count()):
                self._open_controller(index)

    def _open_controller(self, index: int) -> None:
        from pygame._sdl2 import controller

        if controller.is_controller(index) and index not in self._controllers:
            self._controllers[index] = controller.Controller(index)
            self.gamepad_seen = True

    def _press(self, name: str) -> None:
        if name not in self._held:
            self._pressed.add(name)
        self._held.add(name)

    def handle(self, event: pygame.event.Event) -> None:
        """Update the state with one pygame event (others are ignored)."""
        kind = event.type
        if kind == pygame.QUIT:
            self._pressed.add("window_close")
        elif kind == pygame.KEYDOWN:
            self._press(pygame.key.name(event.key))
        elif kind == pygame.KEYUP:
            self._held.discard(pygame.key.name(event.key))
        elif kind == pygame.MOUSEBUTTONDOWN and event.button == 1:
            for name, (cx, cy, r) in self.sticks.items():
                if (event.pos[0] - cx) ** 2 + (event.pos[1] - cy) ** 2 <= r * r:
                    self._drag = name
                    self._set_stick(name, event.pos)
        elif kind == pygame.MOUSEMOTION and self._drag is not None:
            self._set_stick(self._drag, event.pos)
        elif kind == pygame.MOUSEBUTTONUP and event.button == 1 and self._drag is not None:
            self._axes[f"mouse_{self._drag}x"] = 0.0
            self._axes[f"mouse_{self._drag}y"] = 0.0
            self._drag = None
        elif kind == pygame.CONTROLLERAXISMOTION and event.axis in _AXES:
            name, sign = _AXES[event.axis]
            self._axes[name] = max(-1.0, min(1.0, sign * event.value / 32767.0))
            self.gamepad_seen = True
        elif kind == pygame.CONTROLLERBUTTONDOWN and event.button in _BUTTONS:
            self._press(_BUTTONS[event.button])
            self.gamepad_seen = True
        elif kind == pygame.CONTROLLERBUTTONUP and event.button in _BUTTONS:
            self._held.discard(_BUTTONS[event.button])
        elif kind == pygame.CONTROLLERDEVICEADDED:
            self._open_controller(event.device_index)
        elif kind == pygame.CONTROLLERDEVICEREMOVED:
            # The pad is gone: release everything it held so nothing stays pushed.
            self._held = {b for b in self._held if not b.startswith("pad_")}
            self._axes = {k: v for k, v in self._axes.items() if not k.startswith("pad_")}
        elif kind == pygame.WINDOWFOCUSLOST:
            # Key-up events are not delivered to an unfocused window: drop held keys.
            self._held.clear()
            self._drag = None
            self._axes = {k: 0.0 for k in self._axes}

    def _set_stick(self, name: str, pos: Sequence[int]) -> None:
        cx, cy, r = self.sticks[name]
        self._axes[f"mouse_{name}x"] = max(-1.0, min(1.0, (pos[0] - cx) / r))
        self._axes[f"mouse_{name}y"] = max(-1.0, min(1.0, -(pos[1] - cy) / r))

    def handle_all(self, events: Iterable[pygame.event.Event]) -> None:
        for event in events:
            self.handle(event)

    def snapshot(self, now: float) -> InputState:
        """The current state; rising edges are reported once, then cleared."""
        pressed = frozenset(self._pressed)
        self._pressed.clear()
        source = "gamepad" if self.gamepad_seen else "keyboard"
        return InputState(
            t=now,
            source=source,
            buttons=frozenset(self._held),
            pressed=pressed,
            axes=dict(self._axes),
        )


class ScriptInput:
    """Replays snapshots one per call (then repeats ``idle``), for tests and benchmarks."""

    def __init__(self, states: Iterable[InputState], idle: InputState | None = None) -> None:
        self._states = list(states)
        self._k = 0
        self.idle = idle

    def __call__(self, now: float) -> InputState:
        if self._k < len(self._states):
            state = self._states[self._k]
            self._k += 1
            return InputState(**{**state.__dict__, "t": now})
        if self.idle is not None:
            return InputState(**{**self.idle.__dict__, "t": now})
        return InputState(t=now, source="script")
