"""The 2D teleop window (pygame): the env, a status line, the bindings and two mouse sticks.

``kinder teleop kinder/<2D id>`` runs :class:`Teleop2DApp`. The window shows the env's rendering,
a status line (id, seed, step, success, recording, episodes saved, frames per second), the
bindings (:data:`~kinder_gym.teleop.mappers.BINDINGS_2D`) and two on-screen sticks for mouse
users. Input comes from :class:`~kinder_gym.teleop.devices.PygameInput` (events only), so the
window runs and is testable headless with ``SDL_VIDEODRIVER=dummy`` by posting events.
"""

from __future__ import annotations

import collections
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pygame

import kinder_core
from kinder_gym.demos.record import EpisodeRecord
from kinder_gym.teleop.devices import PygameInput
from kinder_gym.teleop.inputs import InputState
from kinder_gym.teleop.loop import Clock, TeleopLoop
from kinder_gym.teleop.mappers import BINDINGS_2D, Mapper, Teleop2DMapper

PANEL = 240
STATUS = 26
STICK_R = 48
_BG = (30, 30, 34)
_FG = (230, 230, 230)


class Teleop2DApp:
    """A pygame window around a :class:`~kinder_gym.teleop.loop.TeleopLoop`.

    Args:
        env_id: A registered 2D id (or a 3D one with a ``mapper`` and ``render`` given).
        seed: First episode's seed.
        save: Called with each saved episode (see the loop).
        hz: Control (and drawing) rate.
        clock: Injected clock (tests).
        height: Height in pixels of the env view.
        open_controllers: Open the game controllers SDL knows at start.
        auto_save: Save successful episodes automatically.
        mapper: Override the mapper (the 3D keyboard fallback passes its own).
        env: Use this env instead of making ``env_id`` (with ``render_mode="rgb_array"``).
        bindings: Lines of the bindings panel.
        render: Frame to show; default ``env.render()``.
    """

    def __init__(
        self,
        env_id: str,
        *,
        seed: int = 0,
        save: Callable[[EpisodeRecord], object] | None = None,
        hz: float = 20.0,
        clock: Clock | None = None,
        height: int = 540,
        open_controllers: bool = True,
        auto_save: bool = True,
        mapper: Mapper | None = None,
        env: Any = None,
        bindings: tuple[tuple[str, str], ...] = BINDINGS_2D,
        render: Callable[[], np.ndarray[Any, Any]] | None = None,
    ) -> None:
        pygame.display.init()
        pygame.font.init()
        self.env = env if env is not None else kinder_core.make(env_id, render_mode="rgb_array")
        self.bindings = bindings
        self._render = render or (lambda: np.asarray(self.env.render()))
        self.mapper = mapper if mapper is not None else Teleop2DMapper(self.env)
        self.loop = TeleopLoop(
            self.env,
            env_id,
            self.mapper,
            self._poll,
            save=save,
            seed=seed,
            hz=hz,
            clock=clock,
            auto_save=auto_save,
            metadata={"device": "pygame", "bindings": "BINDINGS_2D" if mapper is None else ""},
        )
        frame = self._render()
        self.view_h = int(height)
        self.view_w = max(1, round(frame.shape[1] * self.view_h / frame.shape[0]))
        size = (self.view_w + PANEL, self.view_h + STATUS)
        self.screen = pygame.display.set_mode(size)
        pygame.display.set_caption(f"KinDER teleop: {env_id}")
        cx = self.view_w + PANEL // 2
        sticks = {
            "l": (cx - PANEL // 4 - 4, self.view_h - STICK_R - 12, STICK_R),
            "r": (cx + PANEL // 4 + 4, self.view_h - STICK_R - 12, STICK_R),
        }
        self.device = PygameInput(sticks, open_controllers=open_controllers)
        self.font = pygame.font.Font(None, 20)
        self._panel = pygame.Surface((PANEL - 12, 18 * len(bindings)))
        self._panel.fill(_BG)
        for i, (key, what) in enumerate(bindings):
            self._panel.blit(self.font.render(key, True, (250, 210, 120)), (0, 18 * i))
            self._panel.blit(self.font.render(what, True, _FG), (98, 18 * i))
        self._frame_times: collections.deque[float] = collections.deque(maxlen=60)
        self.frames = 0

    def _poll(self, now: float) -> InputState:
        self.device.handle_all(pygame.event.get())
        return self.device.snapshot(now)

    @property
    def fps(self) -> float:
        """Frames drawn per second over the last 60 frames."""
        times = self._frame_times
        if len(times) < 2 or times[-1] <= times[0]:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def draw(self) -> None:
        """Draw the env view, the panel and the status line, then flip."""
        screen = self.screen
        screen.fill(_BG)
        frame = np.ascontiguousarray(self._render()[:, :, :3], dtype=np.uint8)
        surface = pygame.image.frombuffer(frame.data, (frame.shape[1], frame.shape[0]), "RGB")
        if surface.get_size() != (self.view_w, self.view_h):
            surface = pygame.transform.scale(surface, (self.view_w, self.view_h))
        screen.blit(surface, (0, 0))
        x0 = self.view_w + 10
        y = 10 + 18 * len(self.bindings)
        screen.blit(self._panel, (x0, 10))
        grip = self.loop.status.info.get("grip")
        if grip is not None:
            text = f"grip: {'ON' if grip else 'off'}"
            screen.blit(self.font.render(text, True, _FG), (x0, y + 6))
        for name, (cx, cy, r) in self.device.sticks.items():
            pygame.draw.circle(screen, (90, 90, 100), (int(cx), int(cy)), int(r), 2)
            ax = self.device._axes.get(f"mouse_{name}x", 0.0)
            ay = self.device._axes.get(f"mouse_{name}y", 0.0)
            knob = (int(cx + ax * r), int(cy - ay * r))
            pygame.draw.circle(screen, (200, 200, 210), knob, 10)
        status = f"{self.loop.status.line()} | {self.fps:.0f} fps"
        screen.blit(self.font.render(status, True, _FG), (6, self.view_h + 5))
        pygame.display.flip()
        self._frame_times.append(time.perf_counter())
        self.frames += 1

    def run(self, max_ticks: int | None = None) -> None:
        """Run until Esc / window close (or ``max_ticks``)."""
        self.loop.run(max_ticks=max_ticks, after_tick=self.draw)

    def close(self) -> None:
        self.env.close()
        pygame.display.quit()
