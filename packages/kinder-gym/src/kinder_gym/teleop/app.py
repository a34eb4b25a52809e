"""Entry points of ``kinder teleop``: pick the front end for an env and run it.

* 2D envs: the pygame window (:class:`~kinder_gym.teleop.gui2d.Teleop2DApp`), 20 Hz by default.
* 3D envs with ``web=True``: the web app (:func:`kinder_gym.teleop.web.server.serve`), 10 Hz.
* 3D envs without: the same pygame window as the keyboard/gamepad fallback, driving the
  :class:`~kinder_gym.teleop.mapper3d.TidyBotTeleop` mapper with velocity bindings
  (:data:`~kinder_gym.teleop.mapper3d.BINDINGS_3D`) and showing the overview and wrist cameras.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

import kinder_core
from kinder_gym.demos.record import EpisodeRecord
from kinder_gym.teleop.loop import Clock
from kinder_gym.teleop.mappers import ROBOT_KINDS_2D, robot_type_name

if TYPE_CHECKING:
    from kinder_gym.teleop.gui2d import Teleop2DApp

DEFAULT_HZ_2D = 20.0
DEFAULT_HZ_3D = 10.0


def is_2d(env_id: str) -> bool:
    """Whether ``env_id``'s robot is one of the 2D robots."""
    env = kinder_core.make(env_id)
    try:
        return robot_type_name(env) in ROBOT_KINDS_2D
    finally:
        env.close()


def make_window(
    env_id: str,
    *,
    seed: int = 0,
    save: Callable[[EpisodeRecord], object] | None = None,
    hz: float | None = None,
    auto_save: bool = True,
    clock: Clock | None = None,
    open_controllers: bool = True,
) -> Teleop2DApp:
    """The pygame window for ``env_id``: 2D, or the 3D keyboard/gamepad fallback."""
    from kinder_gym.teleop.gui2d import Teleop2DApp

    if is_2d(env_id):
        return Teleop2DApp(
            env_id,
            seed=seed,
            save=save,
            hz=hz or DEFAULT_HZ_2D,
            auto_save=auto_save,
            clock=clock,
            open_controllers=open_controllers,
        )
    from kinder_gym.teleop.mapper3d import BINDINGS_3D, TidyBotTeleop
    from kinder_gym.teleop.web.frames import render_views, set_image_size

    rate = hz or DEFAULT_HZ_3D
    env = kinder_core.make(env_id, render_mode="rgb_array")
    set_image_size(env, 480, 270)

    def render() -> np.ndarray[Any, Any]:
        views = render_views(env)
        names = [n for n in views if "wrist" in n or n in ("overview", "task_view")]
        chosen = [views[n] for n in sorted(names)] or list(views.values())[:2]
        return np.concatenate([v[:, :, :3] for v in chosen], axis=0)

    return Teleop2DApp(
        env_id,
        seed=seed,
        save=save,
        hz=rate,
        auto_save=auto_save,
        env=env,
        mapper=TidyBotTeleop(env, hz=rate),
        bindings=BINDINGS_3D,
        render=render,
        height=540,
        clock=clock,
        open_controllers=open_controllers,
    )


def run_window(
    env_id: str,
    *,
    seed: int = 0,
    save: Callable[[EpisodeRecord], object] | None = None,
    hz: float | None = None,
    auto_save: bool = True,
    max_ticks: int | None = None,
) -> Teleop2DApp:
    """Run the pygame window (2D, or the 3D keyboard/gamepad fallback) until it is closed."""
    app = make_window(env_id, seed=seed, save=save, hz=hz, auto_save=auto_save)
    try:
        app.run(max_ticks=max_ticks)
    finally:
        app.close()
    return app
