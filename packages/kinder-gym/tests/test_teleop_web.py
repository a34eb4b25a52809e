"""The web app's protocol through FastAPI's test client (no browser): hub, deadman, staleness."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("kinder_garden3d")

from fastapi.testclient import TestClient

from kinder_gym.demos.record import EpisodeRecord
from kinder_gym.teleop.loop import FakeClock
from kinder_gym.teleop.web.hub import WebHub
from kinder_gym.teleop.web.protocol import VERSION, ProtocolError, parse_message
from kinder_gym.teleop.web.server import WebTeleop

ENV_ID = "kinder/BaseMotion3D-v0"


def msg(
    seq: int, sent: float | None = None, engaged: tuple[str, ...] = ("base",), **extra: Any
) -> str:
    data: dict[str, Any] = {
        "v": VERSION,
        "type": "input",
        "seq": seq,
        "device": "script",
        "engaged": list(engaged),
        "poses": {
            "base": {
                "grab": extra.pop("grab", 1),
                "p": [0.0, 0.0, extra.pop("z", 0.0)],
                "q": [0.0, 0.0, 0.0, 1.0],
            }
        },
        **extra,
    }
    if sent is not None:
        data["sent"] = sent
    return json.dumps(data)


def reply(ws: Any, kind: str | None = None) -> dict[str, Any]:
    """The next non-status message."""
    for _ in range(100):
        data = ws.receive_json()
        if data["type"] != "status":
            assert kind is None or data["type"] == kind, data
            return dict(data)
    raise AssertionError("no reply")


@pytest.fixture(scope="module")
def teleop():  # type: ignore[no-untyped-def]
    saved: list[EpisodeRecord] = []
    # claim_after=1: each message takes effect at once (the claim rule is tested in
    # test_teleop_phone_ar.py).
    t = WebTeleop(
        ENV_ID, seed=0, save=saved.append, clock=FakeClock(), frame_every=1, claim_after=1
    )
    t.saved_records = saved  # type: ignore[attr-defined]
    yield t
    t.close()


def base(t: WebTeleop) -> np.ndarray:  # type: ignore[type-arg]
    return t.mapper.measured(t.env)[0]


def test_parse_errors_name_the_problem() -> None:
    with pytest.raises(ProtocolError, match="not valid JSON"):
        parse_message("{oops")
    with pytest.raises(ProtocolError, match="version"):
        parse_message('{"v": 1, "type": "input", "seq": 0}')  # version 1 is gone
    with pytest.raises(ProtocolError, match="seq"):
        parse_message('{"v": 2, "type": "input", "seq": -1}')
    with pytest.raises(ProtocolError, match="unit quaternion"):
        parse_message('{"v":2,"type":"input","seq":0,"poses":{"arm":{"p":[0,0,0],"q":[0,0,0,2]}}}')
    with pytest.raises(ProtocolError, match="engaged"):
        parse_message('{"v":2,"type":"input","seq":0,"engaged":["leg"]}')
    with pytest.raises(ProtocolError, match="gripper"):
        parse_message('{"v":2,"type":"input","seq":0,"gripper":1.5}')
    with pytest.raises(ProtocolError, match="unknown event"):
        parse_message('{"v":2,"type":"event","name":"explode"}')
    ok = parse_message(msg(3, 10.0))
    assert ok.seq == 3 and ok.engaged == {"base"}  # type: ignore[union-attr]


def test_token_is_required(teleop: WebTeleop) -> None:
    client = TestClient(teleop.app)
    teleop.after_tick()  # renders the cameras (frame_every=1) in this, the loop's thread
    assert teleop.hub.status()["cameras"] == ["base", "overview", "wrist"]
    assert client.get("/").status_code == 403
    page = client.get(f"/?token={teleop.token}")
    assert (
        page.status_code == 200
        and "<script>" in page.text
        and "http" not in page.text.split("<script>")[0].replace("http-equiv", "")
    )
    assert client.get(f"/frame/overview.jpg?token={teleop.token}").content[:2] == b"\xff\xd8"
    with pytest.raises(Exception), client.websocket_connect("/ws?token=wrong") as ws:  # noqa: B017
        ws.receive_json()


def test_clutch_deadman_stale_and_malformed(teleop: WebTeleop) -> None:
    clock = teleop.loop.clock
    assert isinstance(clock, FakeClock)
    client = TestClient(teleop.app)
    with client.websocket_connect(f"/ws?token={teleop.token}") as ws:
        hello = reply(ws, "hello")
        assert hello["env_id"] == ENV_ID and hello["max_age_ms"] == 250.0
        start = base(teleop)
        # Grab 1 of the base clutch: the device reports 0.1 m forward (WebXR −z) already in its
        # first message (the grab is anchored where it began), then 0.2 m.
        assert reply_to(ws, msg(0, 1000.0, z=-0.1))["type"] == "ack"
        teleop.loop.tick()
        assert reply_to(ws, msg(1, 1001.0, z=-0.2))["type"] == "ack"
        for _ in range(6):
            teleop.loop.tick()
            clock.t += 0.01
        moved = base(teleop) - start
        assert moved[0] == pytest.approx(0.2, abs=1e-6) and abs(moved[1]) < 1e-9
        # Malformed JSON: an error reply, and nothing changes.
        steps = teleop.loop.status.step
        assert reply_to(ws, "{not json")["type"] == "error"
        assert reply_to(ws, '{"v": 2, "type": "input", "seq": "x"}')["type"] == "error"
        # Out of order and stale messages are dropped.
        assert reply_to(ws, msg(1, 1002.0, z=-1.0)) == {
            "v": VERSION,
            "type": "dropped",
            "seq": 1,
            "reason": "out_of_order",
        }
        assert reply_to(ws, msg(5, 1002.0 - 400.0, z=-1.0))["reason"] == "stale"
        teleop.loop.tick()
        assert base(teleop)[0] == pytest.approx(start[0] + 0.2, abs=1e-6)
        assert teleop.loop.status.step == steps + 1  # held still at its target
        # Deadman released: paused (no step), the target snaps to the measured pose.
        assert reply_to(ws, msg(6, 1003.0, engaged=(), z=-1.0))["type"] == "ack"
        teleop.loop.tick()
        assert teleop.loop.status.paused and teleop.loop.status.step == steps + 1
        # A new grab starts from where the robot is: no jump, then 0.05 m more.
        assert reply_to(ws, msg(7, 1004.0, grab=2, z=0.0))["type"] == "ack"
        teleop.loop.tick()
        assert base(teleop)[0] == pytest.approx(start[0] + 0.2, abs=1e-6)
        assert reply_to(ws, msg(8, 1004.0, grab=2, z=-0.05))["type"] == "ack"
        teleop.loop.tick()
        assert base(teleop)[0] == pytest.approx(start[0] + 0.25, abs=1e-6)
        # A sample older than max_age (server clock) counts as released.
        clock.t += 0.3
        teleop.loop.tick()
        assert teleop.loop.status.paused
        # Episode events from the page.
        ws.send_text('{"v": 2, "type": "event", "name": "save"}')
        assert reply(ws)["type"] == "event_ack"
        teleop.loop.tick()
        saved: list[EpisodeRecord] = teleop.saved_records  # type: ignore[attr-defined]
        assert len(saved) == 1 and saved[0].num_steps == steps + 3 and not saved[0].terminated
        assert teleop.loop.status.seed == 1
    # The status the page shows reaches the hub.
    teleop.after_tick()
    assert teleop.hub.status()["seed"] == 1


def reply_to(ws: Any, text: str) -> dict[str, Any]:
    ws.send_text(text)
    return reply(ws)


def test_one_client_per_channel_after_consecutive_messages() -> None:
    hub = WebHub(clock=lambda: 0.0)  # claim_after = 3
    a, b = hub.connect(), hub.connect()
    # a's first two engaged messages only count towards the claim.
    assert hub.handle_text(a, msg(0)) == {"v": VERSION, "type": "ack", "seq": 0, "control": []}
    assert hub.handle_text(a, msg(1))["control"] == []
    assert not hub.poll(0.0).enabled
    assert hub.handle_text(a, msg(2))["control"] == ["base"]
    assert hub.poll(0.0).engaged == {"base"}
    # b asks for the base a holds: dropped, three times over; b only watches.
    for seq in range(3):
        assert hub.handle_text(b, msg(seq))["reason"] == "not_in_control"
    watched = json.dumps({"v": VERSION, "type": "input", "seq": 5, "engaged": []})
    assert hub.handle_text(b, watched)["control"] == []
    event = '{"v": 2, "type": "event", "name": "save"}'
    assert hub.handle_text(b, event)["reason"] == "not_in_control"  # a watcher's event
    assert hub.handle_text(a, event)["type"] == "event_ack"
    hub.disconnect(a)
    assert not hub.poll(0.0).enabled  # the controller left: released
    for seq in range(6, 9):
        reply_b = hub.handle_text(b, msg(seq))
    assert reply_b["control"] == ["base"]
    state = hub.poll(0.0)
    assert state.enabled and state.received == 0.0
    assert hub.poll(0.0).received is None  # latency counted once per message
