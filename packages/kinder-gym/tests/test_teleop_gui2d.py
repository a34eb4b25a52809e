"""The 2D teleop window, headless (SDL dummy driver), driven by posted pygame events."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

pygame = pytest.importorskip("pygame")

import kinder_core  # noqa: E402
from kinder_gym.demos.lerobot_format import load_records  # noqa: E402
from kinder_gym.demos.record import EpisodeRecord  # noqa: E402
from kinder_gym.demos.replay import replay_record  # noqa: E402
from kinder_gym.demos.store import load_record  # noqa: E402
from kinder_gym.teleop.gui2d import Teleop2DApp  # noqa: E402
from kinder_gym.teleop.loop import FakeClock  # noqa: E402
from kinder_gym.teleop.saving import TeleopSaver  # noqa: E402

ENV_ID = "kinder/Motion2D-p0-v0"


def key(kind: int, k: int) -> None:
    pygame.event.post(pygame.event.Event(kind, key=k, mod=0, unicode="", scancode=0))


def hold(app: Teleop2DApp, k: int, ticks: int) -> None:
    key(pygame.KEYDOWN, k)
    app.run(max_ticks=ticks)
    key(pygame.KEYUP, k)


def replay(record: EpisodeRecord) -> bool:
    """Replay a record's actions from its seed; True when observations and success match."""
    env = kinder_core.make(record.env_id)
    obs, _ = env.reset(seed=record.seed)
    ok = np.allclose(obs, record.observations[0])
    terminated = False
    for t, action in enumerate(record.actions):
        obs, _, terminated, _, _ = env.step(action)
        ok = ok and np.allclose(obs, record.observations[t + 1])
    env.close()
    return bool(ok and terminated == record.terminated)


@pytest.fixture
def app():  # type: ignore[no-untyped-def]
    saved: list[EpisodeRecord] = []
    application = Teleop2DApp(
        ENV_ID, seed=0, save=saved.append, clock=FakeClock(), open_controllers=False, height=300
    )
    application.saved_records = saved  # type: ignore[attr-defined]
    pygame.event.clear()
    yield application
    application.close()


def solve_by_keys(app: Teleop2DApp) -> EpisodeRecord:
    """Post the key events that drive Motion2D-p0's robot into its target region."""
    state = app.env.unwrapped.get_state()
    robot = state.get_object_from_name("robot")
    region = state.get_object_from_name("target_region")
    gx = state.get(region, "x") + state.get(region, "width") / 2
    gy = state.get(region, "y") + state.get(region, "height") / 2
    dx, dy = gx - state.get(robot, "x"), gy - state.get(robot, "y")
    step = 0.05
    # Idle ticks step the env too (fixed rate): a zero action, recorded.
    app.run(max_ticks=2)
    assert app.loop.status.step == 2
    hold(app, pygame.K_d, round(dx / step))
    hold(app, pygame.K_w if dy > 0 else pygame.K_s, round(abs(dy) / step))
    app.run(max_ticks=1)  # the key-up tick (no motion): success is reached by now
    saved: list[EpisodeRecord] = app.saved_records  # type: ignore[attr-defined]
    assert len(saved) == 1, app.loop.status.line()
    return saved[0]


def test_scripted_keys_solve_motion2d_and_the_demo_replays(
    app: Teleop2DApp, tmp_path: Path
) -> None:
    record = solve_by_keys(app)
    assert record.terminated and record.source == "teleop" and record.seed == 0
    assert record.metadata["end"] == "success"
    assert app.loop.status.seed == 1  # moved on to the next seed
    assert replay(record)
    # Saved through the teleop saver: an atomic episode file that loads back and replays.
    saver = TeleopSaver(tmp_path / "out", ENV_ID)
    path = saver(record)
    assert [p.name for p in saver.files()] == ["episode-000000-seed0.npz"] == [path.name]
    env = kinder_core.make(ENV_ID)
    assert replay_record(env, load_record(path)).ok
    env.close()
    # The window drew the env, the status line and the panel (pixels readable headless).
    pixels = pygame.surfarray.array3d(app.screen)
    assert pixels.shape[0] > app.view_w
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 10
    assert app.frames > 0


@pytest.mark.slow
def test_teleop_demo_into_the_lerobot_dataset_replays(app: Teleop2DApp, tmp_path: Path) -> None:
    """The LeRobot leg (lerobot and torch imports make it slow: ~50 s on a busy 2-core box)."""
    record = solve_by_keys(app)
    saver = TeleopSaver(tmp_path / "out", ENV_ID)
    saver(record)
    assert saver.build(images=False) == 1
    assert saver.build(images=False) == 0  # already in
    loaded = load_records(saver.dataset_dir)
    assert len(loaded) == 1 and loaded[0].metadata["episode_file"] == "episode-000000-seed0.npz"
    np.testing.assert_array_equal(loaded[0].actions, record.actions)
    env = kinder_core.make(ENV_ID)
    assert replay_record(env, loaded[0]).ok
    env.close()


def test_mouse_stick_gamepad_and_manual_events(app: Teleop2DApp) -> None:
    x0 = app.env.unwrapped.get_state()
    robot = x0.get_object_from_name("robot")
    start = (x0.get(robot, "x"), x0.get(robot, "y"))
    cx, cy, r = app.device.sticks["r"]
    pygame.event.post(pygame.event.Event(pygame.MOUSEBUTTONDOWN, pos=(cx, cy), button=1))
    pygame.event.post(
        pygame.event.Event(pygame.MOUSEMOTION, pos=(cx + r, cy), rel=(r, 0), buttons=(1, 0, 0))
    )
    app.run(max_ticks=3)
    pygame.event.post(pygame.event.Event(pygame.MOUSEBUTTONUP, pos=(cx + r, cy), button=1))
    s1 = app.env.unwrapped.get_state()
    assert s1.get(robot, "x") == pytest.approx(start[0] + 0.15)
    # A gamepad: right stick up moves +y; Cross toggles the vacuum on.
    pygame.event.post(
        pygame.event.Event(
            pygame.CONTROLLERAXISMOTION, axis=pygame.CONTROLLER_AXIS_RIGHTY, value=-32767
        )
    )
    pygame.event.post(
        pygame.event.Event(pygame.CONTROLLERBUTTONDOWN, button=pygame.CONTROLLER_BUTTON_A)
    )
    app.run(max_ticks=2)
    s2 = app.env.unwrapped.get_state()
    assert s2.get(robot, "y") > s1.get(robot, "y")
    assert s2.get(robot, "vacuum") == 1.0
    assert app.loop.status.info["grip"] is True
    # Backspace discards (next seed); Enter with steps saves; Esc quits.
    key(pygame.KEYDOWN, pygame.K_BACKSPACE)
    app.run(max_ticks=1)
    assert app.loop.status.seed == 1 and app.loop.status.episodes_discarded == 1
    key(pygame.KEYUP, pygame.K_BACKSPACE)
    app.run(max_ticks=3)
    key(pygame.KEYDOWN, pygame.K_RETURN)
    app.run(max_ticks=1)
    saved: list[EpisodeRecord] = app.saved_records  # type: ignore[attr-defined]
    assert [r.seed for r in saved] == [1] and not saved[0].terminated
    key(pygame.KEYDOWN, pygame.K_ESCAPE)
    app.run(max_ticks=5)
    assert app.loop.quit


def test_3d_keyboard_fallback_window_drives_the_base() -> None:
    pytest.importorskip("kinder_garden3d")
    from kinder_gym.teleop.app import make_window

    window = make_window(
        "kinder/BaseMotion3D-v0", clock=FakeClock(), open_controllers=False, auto_save=False
    )
    pygame.event.clear()
    try:
        robot = window.env.unwrapped.get_state().get_object_from_name("robot")
        key(pygame.KEYDOWN, pygame.K_w)
        window.run(max_ticks=3)
        state = window.env.unwrapped.get_state()
        assert state.get(robot, "pos_base_x") == pytest.approx(0.15)  # 0.5 m/s at 10 Hz
        assert state.get(robot, "pos_base_y") == pytest.approx(0.0)
        assert window.loop.status.step == 3 and window.frames == 3
    finally:
        window.close()
