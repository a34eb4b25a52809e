"""Moving the phone, server side: the viewer pose's reference capture, 1:1 motion about the
phone's centre, the frame conversion into end-effector targets, control per channel after
consecutive messages, stale and out-of-order messages, the clutch release, a pose that jumps by
metres, the message size limit and a clean stop of the server on SIGTERM."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("kinder_garden3d")

from fastapi.testclient import TestClient

import kinder_core
from kinder_garden3d.kinematic3d.geometry import quat_multiply, yaw_quat
from kinder_gym.teleop.mapper3d import Limits, TidyBotTeleop, ee_pose_in_base
from kinder_gym.teleop.web.hub import WebHub
from kinder_gym.teleop.web.protocol import MAX_MESSAGE_BYTES, VERSION, ProtocolError, parse_message
from kinder_gym.teleop.web.server import ServerThread, create_app
from kinder_gym.teleop.web.viewer import DEFAULT_CENTRE_OFFSET, ViewerClutch, quat_rotate

Vec = tuple[float, float, float]


def up_yaw(angle: float) -> tuple[float, float, float, float]:
    """A turn by ``angle`` about WebXR +y (up): the phone turns left."""
    return (0.0, math.sin(angle / 2), 0.0, math.cos(angle / 2))


def camera_at(centre: Vec, q: tuple[float, float, float, float]) -> Vec:
    """The camera position that puts the phone's centre at ``centre`` when turned by ``q``."""
    r = quat_rotate(q, DEFAULT_CENTRE_OFFSET)
    return (centre[0] - r[0], centre[1] - r[1], centre[2] - r[2])


def ar(
    seq: int,
    p: Vec,
    q: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0),
    engaged: tuple[str, ...] = ("arm",),
    sent: float | None = None,
) -> str:
    data: dict[str, Any] = {
        "v": VERSION,
        "type": "input",
        "seq": seq,
        "device": "phone-ar",
        "engaged": list(engaged),
        "viewer": {"p": list(p), "q": list(q)},
    }
    if sent is not None:
        data["sent"] = sent
    return json.dumps(data)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_viewer_clutch_is_one_to_one_about_the_phone_centre() -> None:
    clutch = ViewerClutch()
    p0, q0 = (0.3, 1.4, -0.2), up_yaw(0.5)
    first = clutch.update(p0, q0)  # the first enabled message captures the reference
    assert first.grab == 1 and first.p == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(first.q, (0, 0, 0, 1), atol=1e-15)
    moved = clutch.update((0.4, 1.45, -0.4), q0)  # 1:1 in position
    np.testing.assert_allclose(moved.p, (0.1, 0.05, -0.2), atol=1e-12)
    # Turning the phone about its centre: no translation, the turn itself.
    c0 = np.asarray(p0) + np.asarray(quat_rotate(q0, DEFAULT_CENTRE_OFFSET))
    q1 = quat_multiply(np.asarray(up_yaw(0.3)), np.asarray(q0))
    q1t = (float(q1[0]), float(q1[1]), float(q1[2]), float(q1[3]))
    turned = clutch.update(camera_at((c0[0], c0[1], c0[2]), q1t), q1t)
    np.testing.assert_allclose(turned.p, (0.0, 0.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(turned.q, up_yaw(0.3), atol=1e-12)
    # Turning about the camera instead swings the centre round it.
    swung = clutch.update(p0, q1t)
    assert np.linalg.norm(swung.p) > 0.005
    # A release ends the grab: the next message captures a new reference.
    clutch.release()
    again = clutch.update((5.0, 0.0, 5.0), q1t)
    assert again.grab == 2 and again.p == (0.0, 0.0, 0.0)


def test_viewer_messages_are_validated() -> None:
    ok = parse_message(ar(0, (0.0, 1.0, 0.0)))
    assert ok.viewer is not None and ok.viewer.p == (0.0, 1.0, 0.0)  # type: ignore[union-attr]
    with pytest.raises(ProtocolError, match="one channel at a time"):
        parse_message(ar(0, (0.0, 1.0, 0.0), engaged=("arm", "base")))
    with pytest.raises(ProtocolError, match=r"viewer\.q must be a unit quaternion"):
        parse_message(ar(0, (0.0, 1.0, 0.0), q=(0.0, 0.0, 0.0, 3.0)))
    both = json.loads(ar(0, (0.0, 1.0, 0.0)))
    both["poses"] = {"arm": {"p": [0, 0, 0]}}
    with pytest.raises(ProtocolError, match="either viewer or poses"):
        parse_message(json.dumps(both))


def test_hub_claims_captures_drops_and_frees_per_channel() -> None:
    clock = Clock()
    hub = WebHub(clock=clock)  # claim_after = 3
    a, b, c = hub.connect(), hub.connect(), hub.connect()
    start = (0.1, 1.4, 0.0)
    # Control only after three consecutive engaged messages; the reference is the pose of the
    # first message that has control (the phone moved during the first two: not used).
    assert hub.handle_text(a, ar(0, (9.0, 9.0, 9.0), sent=0.0))["control"] == []
    assert hub.handle_text(a, ar(1, (8.0, 8.0, 8.0), sent=1.0))["control"] == []
    assert not hub.poll(clock.t).enabled
    assert hub.handle_text(a, ar(2, start, sent=2.0))["control"] == ["arm"]
    state = hub.poll(clock.t)
    assert state.enabled and state.engaged == {"arm"} and state.poses["arm"].p == (0, 0, 0)
    grab = state.poses["arm"].grab
    assert hub.handle_text(a, ar(3, (0.15, 1.5, -0.2), sent=3.0))["type"] == "ack"
    np.testing.assert_allclose(hub.poll(clock.t).poses["arm"].p, (0.05, 0.1, -0.2), atol=1e-12)
    # Out of order and stale messages are dropped and change nothing.
    assert hub.handle_text(a, ar(3, (5.0, 5.0, 5.0), sent=4.0))["reason"] == "out_of_order"
    assert hub.handle_text(a, ar(9, (5.0, 5.0, 5.0), sent=4.0 - 400.0))["reason"] == "stale"
    np.testing.assert_allclose(hub.poll(clock.t).poses["arm"].p, (0.05, 0.1, -0.2), atol=1e-12)
    # A second phone drives the base at the same time; a third asks for the arm: refused.
    for seq in range(3):
        hub.handle_text(b, ar(seq, (0.0, 1.2, 0.0), engaged=("base",)))
    assert hub.handle_text(b, ar(3, (0.0, 1.2, -0.3), engaged=("base",)))["control"] == ["base"]
    for seq in range(4):
        assert hub.handle_text(c, ar(seq, (0.0, 1.0, 0.0)))["reason"] == "not_in_control"
    state = hub.poll(clock.t)
    assert state.engaged == {"arm", "base"}
    np.testing.assert_allclose(state.poses["base"].p, (0.0, 0.0, -0.3), atol=1e-12)
    assert state.poses["base"].grab != grab
    # The arm phone lifts its finger: the arm channel is free; c (still asking) takes it with a
    # new grab and its own reference.
    assert hub.handle_text(a, ar(10, (3.0, 3.0, 3.0), engaged=(), sent=10.0))["control"] == []
    assert hub.poll(clock.t).engaged == {"base"}
    assert hub.handle_text(c, ar(4, (0.0, 1.0, 0.5)))["control"] == ["arm"]
    state = hub.poll(clock.t)
    assert state.poses["arm"].grab not in (grab, state.poses["base"].grab)
    assert state.poses["arm"].p == (0.0, 0.0, 0.0)
    # Samples older than max_age (server clock) count as released; a disconnect frees too.
    clock.t += 0.3
    assert not hub.poll(clock.t).enabled
    hub.disconnect(b)
    assert hub.controls(b) == []


def test_size_limit_error_reply_changes_nothing() -> None:
    clock = Clock()
    hub = WebHub(clock=clock, claim_after=1)
    app = create_app(hub, "tok")
    big = ar(1, (0.0, 1.0, 0.0)).replace('"device"', '"pad": "' + "x" * 2_000_000 + '", "device"')
    assert len(big) > MAX_MESSAGE_BYTES
    with TestClient(app).websocket_connect("/ws?token=tok") as ws:
        assert ws.receive_json()["type"] == "hello"

        def reply(text: str | bytes) -> dict[str, Any]:
            ws.send_text(text) if isinstance(text, str) else ws.send_bytes(text)
            while True:
                data = ws.receive_json()
                if data["type"] != "status":
                    return dict(data)

        assert reply(ar(0, (0.0, 1.0, 0.0)))["control"] == ["arm"]
        before = hub.poll(clock.t)
        for message in (big, big.encode()):
            error = reply(message)
            assert error["type"] == "error"
            assert f"larger than the limit of {MAX_MESSAGE_BYTES} bytes" in error["message"]
        after = hub.poll(clock.t)
        assert (after.poses, after.engaged) == (before.poses, before.engaged)
        assert hub.received == 1 and hub.dropped == 0
        # The connection lives on: the next message (even as a binary frame) is taken.
        assert reply(ar(2, (0.0, 1.0, -0.1)).encode())["type"] == "ack"
    # The same through the real server (uvicorn): its frame limit is above 2 MB, so the 2 MB
    # message reaches the hub and gets the error reply.
    from websockets.sync.client import connect

    http = ServerThread(app)
    port = http.start()
    try:
        with connect(f"ws://127.0.0.1:{port}/ws?token=tok", max_size=None) as ws:
            ws.send(big)
            while (data := json.loads(ws.recv(timeout=30)))["type"] in ("hello", "status"):
                pass
            assert data["type"] == "error" and "larger than the limit" in data["message"]
    finally:
        http.stop()


@pytest.fixture
def shelf():  # type: ignore[no-untyped-def]
    env = kinder_core.make("kinder/Shelf3D-o1-v0")
    env.reset(seed=1000)
    yield env
    env.close()


def drive(hub: WebHub, mapper: TidyBotTeleop, env: Any, clock: Clock, ticks: int) -> Any:
    out = None
    for _ in range(ticks):
        out = mapper(hub.poll(clock.t), env)
        if out.action is not None:
            assert np.all(out.action >= env.action_space.low)
            assert np.all(out.action <= env.action_space.high)
            env.step(out.action)
    return out


def test_known_phone_motion_gives_known_hand_target(shelf: Any) -> None:
    clock = Clock()
    hub = WebHub(clock=clock, claim_after=1)
    mapper = TidyBotTeleop(shelf, hz=10)
    a = hub.connect()
    _, arm0 = mapper.measured(shelf)
    p0, q0 = ee_pose_in_base(arm0)
    hub.handle_text(a, ar(0, (0.0, 1.4, 0.0)))
    drive(hub, mapper, shelf, clock, 1)
    # 5 cm right, 10 cm up, 10 cm forward (WebXR −z) → robot −y 5 cm, +z 10 cm, +x 10 cm.
    hub.handle_text(a, ar(1, (0.05, 1.5, -0.1)))
    drive(hub, mapper, shelf, clock, 20)
    np.testing.assert_allclose(mapper.ee_p, p0 + np.array([0.1, -0.05, 0.1]), atol=1e-12)
    np.testing.assert_allclose(mapper.ee_q, q0, atol=1e-12)
    _, arm = mapper.measured(shelf)
    np.testing.assert_allclose(ee_pose_in_base(arm)[0], mapper.ee_p, atol=3e-3)
    # Turning the phone 0.3 rad left about its centre turns the hand about the robot's +z and
    # leaves its position.
    centre = np.asarray((0.05, 1.5, -0.1)) + np.asarray(DEFAULT_CENTRE_OFFSET)
    q = up_yaw(0.3)
    hub.handle_text(a, ar(2, camera_at((centre[0], centre[1], centre[2]), q), q))
    drive(hub, mapper, shelf, clock, 8)
    np.testing.assert_allclose(mapper.ee_p, p0 + np.array([0.1, -0.05, 0.1]), atol=1e-9)
    np.testing.assert_allclose(mapper.ee_q, quat_multiply(yaw_quat(0.3), q0), atol=1e-9)


def test_release_freezes_and_a_far_jump_is_clamped(shelf: Any) -> None:
    clock = Clock()
    hub = WebHub(clock=clock, claim_after=1)
    limits = Limits()
    mapper = TidyBotTeleop(shelf, hz=10, limits=limits)
    a = hub.connect()
    hub.handle_text(a, ar(0, (0.0, 1.4, 0.0)))
    hub.handle_text(a, ar(1, (0.0, 1.4, -0.06)))
    drive(hub, mapper, shelf, clock, 15)
    held = mapper.ee_p.copy()
    # Release, then move the phone a long way: paused, the target frozen.
    hub.handle_text(a, ar(2, (0.0, 1.4, -0.06), engaged=()))
    frozen = drive(hub, mapper, shelf, clock, 1)
    assert frozen.action is None
    target = mapper.ee_p.copy()
    np.testing.assert_allclose(target, held, atol=3e-3)
    hub.handle_text(a, ar(3, (0.5, 0.4, 1.0), engaged=()))
    assert drive(hub, mapper, shelf, clock, 3).action is None
    np.testing.assert_allclose(mapper.ee_p, target, atol=0.0)
    # A new grab there, then the phone "jumps" 5 m forward and 3 m up (a tracking glitch): the
    # target moves at most ee_speed / hz per tick and stops at the workspace box.
    hub.handle_text(a, ar(4, (0.5, 0.4, 1.0)))
    drive(hub, mapper, shelf, clock, 1)
    np.testing.assert_allclose(mapper.ee_p, target, atol=1e-12)
    hub.handle_text(a, ar(5, (0.5, 3.4, -4.0)))
    previous = mapper.ee_p.copy()
    for _ in range(40):
        drive(hub, mapper, shelf, clock, 1)
        assert np.linalg.norm(mapper.ee_p - previous) <= limits.ee_speed / 10 + 1e-12
        previous = mapper.ee_p.copy()
    np.testing.assert_allclose(mapper.ee_p[0], limits.workspace_high[0], atol=1e-12)
    np.testing.assert_allclose(mapper.ee_p[2], limits.workspace_high[2], atol=1e-12)


def test_hand_stays_in_the_world_while_another_device_drives_the_base(shelf: Any) -> None:
    clock = Clock()
    hub = WebHub(clock=clock, claim_after=1)
    mapper = TidyBotTeleop(shelf, hz=10)
    arm_phone, base_phone = hub.connect(), hub.connect()
    base0, _ = mapper.measured(shelf)
    hub.handle_text(arm_phone, ar(0, (0.0, 1.4, 0.0)))
    drive(hub, mapper, shelf, clock, 1)
    p0 = mapper.ee_p.copy()
    hub.handle_text(base_phone, ar(0, (0.0, 1.4, 0.0), engaged=("base",)))
    hub.handle_text(base_phone, ar(1, (0.0, 1.4, -0.2), engaged=("base",)))  # 20 cm forward
    hub.handle_text(arm_phone, ar(1, (0.0, 1.4, 0.0)))  # the arm phone holds still
    drive(hub, mapper, shelf, clock, 8)
    base, _ = mapper.measured(shelf)
    np.testing.assert_allclose(
        base[:2] - base0[:2], 0.2 * np.array([math.cos(base0[2]), math.sin(base0[2])]), atol=1e-3
    )
    np.testing.assert_allclose(mapper.ee_p, p0 - np.array([0.2, 0.0, 0.0]), atol=1e-3)


SERVE = textwrap.dedent(
    """
    import sys
    from kinder_gym.teleop.saving import TeleopSaver
    from kinder_gym.teleop.web import server

    saver = TeleopSaver(sys.argv[1], "kinder/BaseMotion3D-v0")
    server.serve("kinder/BaseMotion3D-v0", save=saver, port=0, hz=20.0)
    print("SERVED", len(saver.files()), flush=True)
    """
)


@pytest.mark.slow
@pytest.mark.parametrize("ctrl_c", [False, True], ids=["SIGTERM", "Ctrl+C to the group"])
def test_a_signal_stops_the_server_cleanly_and_keeps_saved_episodes(
    tmp_path: Path, ctrl_c: bool
) -> None:
    """SIGTERM to the server, or SIGINT to its whole process group (what Ctrl+C in a terminal
    does, reaching the camera worker too): exit status 0, no traceback, the saved episode on
    disk."""
    from websockets.sync.client import connect

    proc = subprocess.Popen(
        [sys.executable, "-c", SERVE, str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        start_new_session=True,
    )
    assert proc.stdout is not None
    url = ""
    for line in proc.stdout:
        if line.startswith("KinDER teleop page: "):
            url = line.split(": ", 1)[1].strip()
            break
    assert url, proc.stderr.read() if proc.stderr else ""
    ws_url = url.replace("http://localhost", "ws://127.0.0.1").replace("/?", "/ws?")
    with connect(ws_url) as ws:
        for seq in range(6):
            ws.send(
                json.dumps(
                    {
                        "v": VERSION,
                        "type": "input",
                        "seq": seq,
                        "engaged": ["base"],
                        "poses": {"base": {"grab": 1, "p": [0, 0, -0.01 * seq]}},
                    }
                )
            )
        for _ in range(200):  # wait until the loop has stepped
            status = json.loads(ws.recv(timeout=30))
            if status["type"] == "status" and status["step"] > 0:
                break
        ws.send(json.dumps({"v": VERSION, "type": "event", "name": "save"}))
        for _ in range(200):
            if json.loads(ws.recv(timeout=30))["type"] == "event_ack":
                break
        for _ in range(200):  # wait until the loop has saved it
            status = json.loads(ws.recv(timeout=30))
            if status["type"] == "status" and status["episodes_saved"] == 1:
                break
    if ctrl_c:
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "Error" not in err, err
    assert "SERVED 1" in out
    assert len(list((tmp_path / "episodes").glob("*.npz"))) == 1


def test_an_interrupted_grab_never_jumps(shelf: Any) -> None:
    """Samples going stale mid-grab release the deadman; when they resume, an AR phone's motion
    continues from a new reference and a touch pad's grab (numbered by the device) stays
    frozen until the finger grabs again."""
    clock = Clock()
    hub = WebHub(clock=clock, claim_after=1)
    mapper = TidyBotTeleop(shelf, hz=10)
    phone = hub.connect()
    hub.handle_text(phone, ar(0, (0.0, 1.4, 0.0)))
    drive(hub, mapper, shelf, clock, 1)
    hub.handle_text(phone, ar(1, (0.0, 1.4, -0.05)))
    drive(hub, mapper, shelf, clock, 10)
    clock.t += 0.3  # a Wi-Fi hiccup: the sample is stale, the loop pauses
    assert drive(hub, mapper, shelf, clock, 1).action is None
    paused = mapper.ee_p.copy()
    hub.handle_text(phone, ar(2, (0.0, 1.4, -0.12)))  # the phone moved 7 cm meanwhile
    drive(hub, mapper, shelf, clock, 1)
    np.testing.assert_allclose(mapper.ee_p, paused, atol=1e-12)  # a new reference: no jump
    hub.handle_text(phone, ar(3, (0.0, 1.4, -0.14)))
    drive(hub, mapper, shelf, clock, 1)
    np.testing.assert_allclose(mapper.ee_p, paused + np.array([0.02, 0.0, 0.0]), atol=1e-12)

    touch = hub.connect()

    def pad(seq: int, grab: int, z: float) -> str:
        return json.dumps(
            {
                "v": VERSION,
                "type": "input",
                "seq": seq,
                "device": "phone",
                "engaged": ["base"],
                "poses": {"base": {"grab": grab, "p": [0.0, 0.0, z]}},
            }
        )

    hub.handle_text(touch, pad(0, 1, 0.0))
    drive(hub, mapper, shelf, clock, 1)
    hub.handle_text(touch, pad(1, 1, -0.04))
    drive(hub, mapper, shelf, clock, 2)
    clock.t += 0.3
    drive(hub, mapper, shelf, clock, 1)
    held = mapper.base_target.copy()
    hub.handle_text(touch, pad(2, 1, -0.3))  # the same grab resumes: frozen
    drive(hub, mapper, shelf, clock, 3)
    np.testing.assert_allclose(mapper.base_target, held, atol=1e-12)
    hub.handle_text(touch, pad(3, 2, 0.0))  # the finger grabs again: moves from there
    drive(hub, mapper, shelf, clock, 1)
    hub.handle_text(touch, pad(4, 2, -0.02))
    drive(hub, mapper, shelf, clock, 1)
    yaw = held[2]
    np.testing.assert_allclose(
        mapper.base_target[:2] - held[:2],
        0.02 * np.array([math.cos(yaw), math.sin(yaw)]),
        atol=1e-6,
    )
