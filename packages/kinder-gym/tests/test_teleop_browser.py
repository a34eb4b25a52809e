"""The web page itself in headless Chromium (Playwright): the phone's touch pads and a WebXR
headset emulated by IWER both drive BaseMotion3D's base to its goal; the episode saves.

Needs Debian's ``chromium`` and, for the headset, the npm package ``iwer`` in the repository's
``node_modules`` (``npm ci`` at the root; ``tools/install_system_deps.sh`` does both). Skipped
cleanly when either is missing. Never downloads a browser.
"""

from __future__ import annotations

import functools
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")
pytest.importorskip("kinder_garden3d")
sync_api = pytest.importorskip("playwright.sync_api")

import kinder_core  # noqa: E402
from kinder_gym.demos.record import EpisodeRecord  # noqa: E402
from kinder_gym.teleop.mapper3d import Limits  # noqa: E402
from kinder_gym.teleop.web.server import ServerThread, WebTeleop  # noqa: E402

ENV_ID = "kinder/BaseMotion3D-v0"
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
ROOT = Path(__file__).resolve().parents[3]
IWER = ROOT / "node_modules" / "iwer" / "build" / "iwer.min.js"
M_PER_PX = 0.004  # the page's touch scale
WAIT_MS = 60_000  # an upper bound for a slow CI machine, not a timing assertion

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed")


@functools.cache
def goal(seed: int) -> tuple[float, float]:
    """The target of BaseMotion3D's episode ``seed``. Strokes look it up again each time: on a
    slow machine an episode may hit its 200-step limit and move on to the next seed."""
    env = kinder_core.make(ENV_ID)
    env.reset(seed=seed)
    state = env.unwrapped.get_state()
    target = state.get_object_from_name("target")
    xy = (state.get(target, "x"), state.get(target, "y"))
    env.close()
    return xy


@pytest.fixture(scope="module")
def server() -> Iterator[tuple[WebTeleop, str]]:
    saved: list[EpisodeRecord] = []
    teleop = WebTeleop(
        ENV_ID,
        seed=0,
        save=saved.append,
        hz=20.0,
        limits=Limits(base_speed=2.0),
        frame_every=4,
        frame_size=(160, 90),
    )
    teleop.saved_records = saved  # type: ignore[attr-defined]
    http = ServerThread(teleop.app)
    port = http.start()
    loop = threading.Thread(target=teleop.run, daemon=True)
    loop.start()
    yield teleop, f"http://127.0.0.1:{port}/?token={teleop.token}"
    teleop.loop.quit = True
    loop.join(timeout=10)
    http.stop()
    teleop.close()


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(
            executable_path=CHROMIUM,
            headless=True,
            args=["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
        )
        yield b
        b.close()


def wait_saved(page: Any, count: int) -> None:
    page.wait_for_function(
        f"window.__kinder.status && window.__kinder.status.episodes_saved >= {count}",
        timeout=WAIT_MS,
    )


def wait_base(page: Any, x: float, y: float, tol: float = 0.01) -> None:
    """Wait until the status shows the base at (x, y) or the episode was saved."""
    page.wait_for_function(
        """([x, y, tol, seed]) => { const s = window.__kinder.status;
             return s && (s.seed !== seed || Math.hypot(s.base[0] - x, s.base[1] - y) < tol); }""",
        arg=[x, y, tol, page.evaluate("window.__kinder.status.seed")],
        timeout=WAIT_MS,
    )


def grabbed(page: Any, channel: str, held: bool) -> None:
    """Wait until the page's XR frame loop has seen the grip pressed (or released): its frames
    run at the emulator's pace, which a loaded machine slows down."""
    check = "!==" if held else "==="
    page.wait_for_function(f"xrGrab.{channel} {check} null", timeout=WAIT_MS)


def test_phone_touch_pads_drive_the_base_to_its_goal(
    server: tuple[WebTeleop, str], browser: Any, tmp_path: Path
) -> None:
    teleop, url = server
    context = browser.new_context(has_touch=True, viewport={"width": 420, "height": 820})
    page = context.new_page()
    page.goto(url)
    page.wait_for_function(
        "window.__kinder.status && window.__kinder.status.env_id", timeout=WAIT_MS
    )
    saved_before = page.evaluate("window.__kinder.status.episodes_saved")
    pad = page.locator("#basepad").bounding_box()
    cx, cy = pad["x"] + pad["width"] * 0.6, pad["y"] + pad["height"] * 0.35
    cdp = context.new_cdp_session(page)

    def touch(kind: str, x: float, y: float) -> None:
        points = [] if kind == "touchEnd" else [{"x": x, "y": y, "id": 1}]
        cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points})

    # The arm's lift strip: dragging up 25 px raises the hand target 0.1 m; the slider near its
    # top closes the gripper; Restart discards the episode and restarts its seed.
    z0 = page.evaluate("window.__kinder.status.info.ee_target[2]")
    lift = page.locator("#lift").bounding_box()
    lx, ly = lift["x"] + lift["width"] / 2, lift["y"] + lift["height"] / 2
    touch("touchStart", lx, ly)
    for k in range(1, 6):
        touch("touchMove", lx, ly - 5 * k)
    page.wait_for_function(
        f"window.__kinder.status.info.ee_target[2] > {z0 + 0.099}", timeout=WAIT_MS
    )
    touch("touchEnd", 0, 0)
    grip = page.locator("#grip").bounding_box()
    touch("touchStart", grip["x"] + grip["width"] / 2, grip["y"] + 2)
    page.wait_for_function("window.__kinder.status.info.gripper > 0.9", timeout=WAIT_MS)
    touch("touchEnd", 0, 0)
    restarted = page.evaluate("window.__kinder.status.episodes_discarded")
    page.tap("#reset")
    page.wait_for_function(
        f"window.__kinder.status.episodes_discarded > {restarted}", timeout=WAIT_MS
    )
    # The robot faces +x (yaw 0): screen up = +x, screen left = +y. Drag in strokes of at most
    # 0.4 m from where the base is (clutch: each touch re-captures the reference), like a person.
    for _ in range(30):
        status = page.evaluate("window.__kinder.status")
        if status["episodes_saved"] > saved_before:
            break
        bx, by = status["base"][:2]
        gx, gy = goal(status["seed"])
        sx = max(-0.4, min(0.4, gx - bx))
        sy = max(-0.4, min(0.4, gy - by))
        dx_px, dy_px = -sy / M_PER_PX, -sx / M_PER_PX
        touch("touchStart", cx, cy)
        for k in range(1, 11):
            touch("touchMove", cx + dx_px * k / 10, cy + dy_px * k / 10)
        wait_base(page, bx + sx, by + sy)
        touch("touchEnd", 0, 0)
    wait_saved(page, saved_before + 1)
    page.screenshot(path=str(tmp_path / "phone.png"))
    assert (tmp_path / "phone.png").stat().st_size > 1000
    assert page.evaluate("document.querySelector('#views img').dataset.loaded") == "1"
    record = teleop.saved_records[-1]  # type: ignore[attr-defined]
    assert record.terminated and record.metadata["device"] == "web"
    assert page.evaluate("window.__kinder.errors.length") == 0
    context.close()


@pytest.mark.skipif(not IWER.exists(), reason="npm package iwer not installed (npm ci)")
def test_webxr_headset_left_grip_drives_the_base(
    server: tuple[WebTeleop, str], browser: Any, tmp_path: Path
) -> None:
    teleop, url = server
    context = browser.new_context(viewport={"width": 800, "height": 600})
    page = context.new_page()
    page.add_init_script(path=str(IWER))
    page.add_init_script(
        script="window.__xrDevice = new IWER.XRDevice(IWER.metaQuest3);"
        "window.__xrDevice.installRuntime({forceInstall: true});"
    )
    page.goto(url)
    page.wait_for_function(
        "window.__kinder.status && window.__kinder.status.env_id", timeout=WAIT_MS
    )
    page.click("#vr")  # a real click: the user activation WebXR asks for
    page.wait_for_function("window.__kinder.xrFrames > 3", timeout=WAIT_MS)
    # Right controller: squeeze (deadman) and raise it 5 cm: the hand target rises 5 cm; the
    # trigger closes the gripper; A saves the episode by hand.
    right = "window.__xrDevice.controllers.right"
    z0 = page.evaluate("window.__kinder.status.info.ee_target[2]")
    saved_manual = page.evaluate("window.__kinder.status.episodes_saved")
    page.evaluate(f"{right}.position.set(0.2, 1.0, -0.3); {right}.updateButtonValue('squeeze', 1)")
    grabbed(page, "arm", True)
    page.evaluate(f"{right}.position.set(0.2, 1.05, -0.3); {right}.updateButtonValue('trigger', 1)")
    page.wait_for_function(
        f"window.__kinder.status.info.ee_target[2] > {z0 + 0.049}"
        " && window.__kinder.status.info.gripper === 1",
        timeout=WAIT_MS,
    )
    page.evaluate(f"{right}.updateButtonValue('a-button', 1)")
    wait_saved(page, saved_manual + 1)
    page.evaluate(
        f"{right}.updateButtonValue('a-button', 0); {right}.updateButtonValue('trigger', 0);"
        f"{right}.updateButtonValue('squeeze', 0)"
    )
    manual = teleop.saved_records[-1]  # type: ignore[attr-defined]
    assert manual.metadata["end"] == "manual" and manual.num_steps > 0
    saved_before = page.evaluate("window.__kinder.status.episodes_saved")
    left = "window.__xrDevice.controllers.left"
    # Robot +x is WebXR −z and robot +y is WebXR −x. Like a person: squeeze, move the controller
    # at most 0.4 m, release, bring it back, squeeze again (each grab re-captures the reference).
    for _ in range(30):
        status = page.evaluate("window.__kinder.status")
        if status["episodes_saved"] > saved_before:
            break
        bx, by = status["base"][:2]
        gx, gy = goal(status["seed"])
        sx = max(-0.4, min(0.4, gx - bx))
        sy = max(-0.4, min(0.4, gy - by))
        page.evaluate(f"{left}.position.set(-0.2, 1.0, -0.3)")
        page.wait_for_timeout(50)
        page.evaluate(f"{left}.updateButtonValue('squeeze', 1)")
        grabbed(page, "base", True)  # the page saw the squeeze at this position
        for k in range(1, 11):
            page.evaluate(f"{left}.position.set({-0.2 - sy * k / 10}, 1.0, {-0.3 - sx * k / 10})")
            page.wait_for_timeout(20)
        wait_base(page, bx + sx, by + sy)
        page.evaluate(f"{left}.updateButtonValue('squeeze', 0)")
        grabbed(page, "base", False)
    wait_saved(page, saved_before + 1)
    page.evaluate(f"{left}.updateButtonValue('squeeze', 0)")
    page.screenshot(path=str(tmp_path / "xr.png"))
    record = teleop.saved_records[-1]  # type: ignore[attr-defined]
    assert record.terminated and record.metadata["end"] == "success"
    assert page.evaluate("window.__kinder.errors.length") == 0
    context.close()
