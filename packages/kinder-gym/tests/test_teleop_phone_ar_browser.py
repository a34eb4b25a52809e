"""Moving the phone, in headless Chromium: two phones emulated by IWER in ``immersive-ar``
sessions drive Shelf3D-o1 at the same time — one moves the arm by moving the phone along a
scripted path (a translation, a turn about the phone's centre, a clutch release mid-path), the
other drives the base — and the saved episode replays exactly. Without IWER the page says it has
no AR and keeps the touch pads.

The end effector tracks the path in the **world** (the base moves under it meanwhile) within
:data:`POS_TOL` and :data:`ROT_TOL` once it settles. Needs Debian's ``chromium`` and the npm
package ``iwer`` (``npm ci`` at the root); skipped cleanly without them.
"""

from __future__ import annotations

import math
import shutil
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("kinder_garden3d")
sync_api = pytest.importorskip("playwright.sync_api")

import kinder_core  # noqa: E402
from kinder_garden3d.kinematic3d.geometry import quat_multiply, yaw_quat  # noqa: E402
from kinder_gym.demos.record import EpisodeRecord  # noqa: E402
from kinder_gym.demos.replay import replay_record  # noqa: E402
from kinder_gym.teleop.web.server import ServerThread, WebTeleop  # noqa: E402
from kinder_gym.teleop.web.viewer import DEFAULT_CENTRE_OFFSET, quat_rotate  # noqa: E402

ENV_ID = "kinder/Shelf3D-o1-v0"
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
ROOT = Path(__file__).resolve().parents[3]
IWER = ROOT / "node_modules" / "iwer" / "build" / "iwer.min.js"
WAIT_S = 60.0  # an upper bound for a slow CI machine, not a timing assertion
POS_TOL = 0.01  # m: settled end effector vs the path's point, in the world
ROT_TOL = 0.05  # rad

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed")


@pytest.fixture(scope="module")
def server() -> Iterator[tuple[WebTeleop, str, list[EpisodeRecord]]]:
    saved: list[EpisodeRecord] = []
    teleop = WebTeleop(
        ENV_ID,
        seed=1000,
        save=saved.append,
        hz=20.0,
        frame_every=0,
        auto_save=False,
        max_age=2.0,  # two emulated XR pages on a loaded CPU may pause their frames for a while
    )
    http = ServerThread(teleop.app)
    port = http.start()
    loop = threading.Thread(target=teleop.run, daemon=True)
    loop.start()
    yield teleop, f"http://127.0.0.1:{port}/?token={teleop.token}", saved
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


class Phone:
    """One emulated phone: a page with IWER in an ``immersive-ar`` session, touched through CDP."""

    def __init__(self, browser: Any, url: str) -> None:
        self.context = browser.new_context(has_touch=True, viewport={"width": 420, "height": 820})
        self.page = self.context.new_page()
        self.page.add_init_script(path=str(IWER))
        self.page.add_init_script(
            script="window.__xrDevice = new IWER.XRDevice(IWER.metaQuest3);"
            "window.__xrDevice.installRuntime({forceInstall: true});"
        )
        self.page.goto(url)
        self.wait("window.__kinder.status && window.__kinder.arSupported === true")
        self.page.click("#ar")  # a real click: the user activation WebXR asks for
        self.wait("window.__kinder.arFrames > 3")
        # The session's local space starts where the phone was (upright): its origin in the
        # emulator's coordinates.
        device = self.page.evaluate("(d => [d.x, d.y, d.z])(window.__xrDevice.position)")
        viewer = self.page.evaluate("window.__kinder.arPose")
        self.origin = [d - v for d, v in zip(device, viewer[:3], strict=True)]
        self.move((0.0, 1.4, 0.0))
        self.cdp = self.context.new_cdp_session(self.page)

    def wait(self, condition: str) -> None:
        self.page.wait_for_function(condition, timeout=WAIT_S * 1000)

    def move(self, p: tuple[float, float, float], yaw: float = 0.0) -> None:
        """Put the phone's camera at ``p`` (WebXR local space) turned by ``yaw`` about +y, and
        wait until the page has sent that pose."""
        q = (0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2))
        d = [p[i] + self.origin[i] for i in range(3)]
        self.page.evaluate(
            f"window.__xrDevice.position.set({d[0]}, {d[1]}, {d[2]});"
            f"window.__xrDevice.quaternion.set({q[0]}, {q[1]}, {q[2]}, {q[3]})"
        )
        self.wait(
            f"(p => p && Math.hypot(p[0] - {p[0]}, p[1] - {p[1]}, p[2] - {p[2]}) < 1e-5"
            f" && Math.abs(p[4] - {q[1]}) < 1e-5)(window.__kinder.arPose)"
        )

    def hold(self, zone: str) -> None:
        box = self.page.locator(zone).bounding_box()
        x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        points = [{"x": x, "y": y, "id": 1}]
        self.cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": points})

    def release(self) -> None:
        self.cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})

    def controls(self, channel: str) -> None:
        self.wait(f"window.__kinder.control.includes('{channel}')")

    def status(self) -> dict[str, Any]:
        return dict(self.page.evaluate("window.__kinder.status"))


def camera_for_centre(centre: np.ndarray, yaw: float) -> tuple[float, float, float]:
    """Where the camera must be for the phone's centre to be at ``centre`` when turned by
    ``yaw`` (so the turn is about the phone's centre)."""
    q = (0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2))
    r = quat_rotate(q, DEFAULT_CENTRE_OFFSET)
    return (centre[0] - r[0], centre[1] - r[1], centre[2] - r[2])


def ee_world(status: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The measured end effector in the world, from the status (base pose and hand in base)."""
    x, y, yaw = status["base"]
    ee = np.asarray(status["ee"], dtype=np.float64)
    c, s = math.cos(yaw), math.sin(yaw)
    p = np.array([x + c * ee[0] - s * ee[1], y + s * ee[0] + c * ee[1], ee[2]])
    return p, quat_multiply(yaw_quat(yaw), ee[3:])


def settle(phone: Phone, p_goal: np.ndarray, q_goal: np.ndarray) -> tuple[float, float]:
    """Wait (bounded) until the end effector is at the goal; the final errors (m, rad)."""
    deadline = time.monotonic() + WAIT_S
    while True:
        p, q = ee_world(phone.status())
        dp = float(np.linalg.norm(p - p_goal))
        dq = 2.0 * math.acos(min(1.0, abs(float(np.dot(q, q_goal)))))
        if (dp < POS_TOL and dq < ROT_TOL) or time.monotonic() > deadline:
            return dp, dq
        phone.page.wait_for_timeout(100)


def robot_axes(v: np.ndarray) -> np.ndarray:
    """A WebXR-frame vector in the robot's axes (forward −z, left −x, up +y)."""
    return np.array([-v[2], -v[0], v[1]])


@pytest.mark.slow  # about a minute: two emulated XR pages rendering in software
@pytest.mark.skipif(not IWER.exists(), reason="npm package iwer not installed (npm ci)")
def test_phone_moves_the_arm_while_a_second_phone_drives_the_base(
    server: tuple[WebTeleop, str, list[EpisodeRecord]], browser: Any
) -> None:
    _, url, saved = server
    arm, base = Phone(browser, url), Phone(browser, url)
    start = arm.status()
    p_ref, q_ref = ee_world(start)
    yaw0 = start["base"][2]

    def world(v: np.ndarray) -> np.ndarray:
        """A WebXR motion as a world displacement (the user faces the robot's heading)."""
        r = robot_axes(v)
        c, s = math.cos(yaw0), math.sin(yaw0)
        return np.array([c * r[0] - s * r[1], s * r[0] + c * r[1], r[2]])

    centre0 = np.array([0.0, 1.4, 0.0]) + np.array(DEFAULT_CENTRE_OFFSET)
    errors: list[tuple[float, float]] = []
    # Arm phone: hold the arm zone (the clutch); its third message takes control and captures
    # the reference. Then the path: 10 cm forward, then 5 cm right and 5 cm up.
    arm.hold("#ararm")
    arm.controls("arm")
    path = [np.array([0.0, 0.0, -0.10]), np.array([0.05, 0.05, -0.10])]
    arm.move(camera_for_centre(centre0 + path[0], 0.0))
    errors.append(settle(arm, p_ref + world(path[0]), q_ref))
    # Meanwhile the base phone holds the base strip and walks 20 cm forward: the base drives,
    # and the hand stays where the arm phone puts it in the world.
    base.hold("#arbase")
    base.controls("base")
    base.move((0.0, 1.4, -0.2))
    arm.move(camera_for_centre(centre0 + path[1], 0.0))
    base.wait(
        f"Math.hypot(window.__kinder.status.base[0] - {start['base'][0]},"
        f" window.__kinder.status.base[1] - {start['base'][1]}) > 0.19"
    )
    errors.append(settle(arm, p_ref + world(path[1]), q_ref))
    base.release()
    # The arm phone turns 0.3 rad to the left about its centre: the hand turns about the
    # robot's vertical and stays put.
    turn = 0.3
    arm.move(camera_for_centre(centre0 + path[1], turn), yaw=turn)
    q_turned = quat_multiply(yaw_quat(turn), q_ref)
    errors.append(settle(arm, p_ref + world(path[1]), q_turned))
    # Clutch released mid-path: the phone goes back, the hand stays (the target is frozen).
    arm.release()
    arm.wait("window.__kinder.status.paused")  # nobody holds a clutch: the loop pauses
    frozen = arm.status()["info"]["ee_target"]
    steps = arm.status()["step"]
    arm.move(camera_for_centre(centre0, 0.0))
    arm.page.wait_for_timeout(300)
    assert arm.status()["info"]["ee_target"] == frozen and arm.status()["step"] == steps
    errors.append(settle(arm, p_ref + world(path[1]), q_turned))
    # A new grab from there: 5 cm further forward moves the hand 5 cm from where it stopped.
    arm.hold("#ararm")
    arm.controls("arm")
    arm.move(camera_for_centre(centre0 + np.array([0.0, 0.0, -0.05]), 0.0))
    errors.append(settle(arm, p_ref + world(path[1] + np.array([0.0, 0.0, -0.05])), q_turned))
    arm.release()
    assert all(dp < POS_TOL and dq < ROT_TOL for dp, dq in errors), errors
    # The gripper slider (a touch) closes the gripper.
    arm.hold("#argrip")
    arm.wait("window.__kinder.status.info.gripper > 0.4")
    arm.release()
    # Save from the overlay; the episode replays exactly.
    count = len(saved)
    arm.page.click("#arui button[data-event=save]")
    arm.wait(f"window.__kinder.status.episodes_saved > {start['episodes_saved']}")
    assert len(saved) == count + 1
    record = saved[-1]
    assert record.num_steps > 0 and record.metadata["device"] == "web"
    env = kinder_core.make(ENV_ID)
    assert replay_record(env, record).ok
    env.close()
    for phone in (arm, base):
        assert phone.page.evaluate("window.__kinder.errors.length") == 0
        phone.context.close()


def test_without_ar_the_page_says_so_and_keeps_the_touch_pads(
    server: tuple[WebTeleop, str, list[EpisodeRecord]], browser: Any
) -> None:
    _, url, _ = server
    context = browser.new_context(has_touch=True, viewport={"width": 420, "height": 820})
    page = context.new_page()
    page.goto(url)
    page.wait_for_function("window.__kinder.arSupported === false", timeout=WAIT_S * 1000)
    assert page.locator("#ar").is_hidden()
    assert "No AR pose tracking" in page.locator("#arnote").inner_text()
    assert page.locator("#armpad").is_visible() and page.locator("#basepad").is_visible()
    context.close()
