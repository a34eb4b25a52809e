"""The web app's message protocol, version 2 (JSON text frames over one WebSocket).

Client → server:

* ``{"v": 2, "type": "input", "seq": 12, "sent": 1712345678901.5, "device": "phone",
  "engaged": ["arm"], "poses": {"arm": {"grab": 3, "p": [x, y, z], "q": [x, y, z, w]}},
  "gripper": 0.4}`` — one input sample. ``seq`` increases per connection (monotonic); ``sent``
  is the client's clock in ms; ``device`` is ``"phone"`` (touch pads), ``"phone-ar"`` (the AR
  session), ``"xr"`` (a headset) or ``"script"``; ``engaged`` names the clutch channels held now
  (``"arm"``, ``"base"``, ``"gripper"``: the deadman); ``poses`` gives, per channel, the
  device's motion since grab number ``grab`` began (the finger went down or the grip was
  squeezed), in the WebXR frame (+x right, +y up, +z back, metres, quaternion x, y, z, w);
  ``gripper`` (optional) is the closure in [0, 1]. Only ``v``, ``type`` and ``seq`` are
  required.
* The AR session sends ``"viewer": {"p": [x, y, z], "q": [x, y, z, w]}`` instead of ``poses``:
  the phone's raw viewer pose in its ``local`` reference space, every XR frame. ``engaged``
  then names at most one of ``"arm"`` / ``"base"`` (the mode, chosen by where the finger
  touches) and the server captures the reference itself
  (:class:`~kinder_gym.teleop.web.viewer.ViewerClutch`).
* ``{"v": 2, "type": "event", "name": "save" | "discard" | "reset"}`` — an episode event.

Server → client:

* ``{"v": 2, "type": "hello", ...}`` on connect (env id, cameras, limits);
* ``{"v": 2, "type": "ack", "seq": n, "control": ["arm"]}`` for every accepted input, with the
  channels this connection controls now (the page shows the round trip and who drives);
* ``{"v": 2, "type": "event_ack", "name": "save"}`` for every accepted event;
* ``{"v": 2, "type": "dropped", "seq": n, "reason": "stale" | "out_of_order" |
  "not_in_control"}`` (events from a watcher: ``"name"`` instead of ``"seq"``);
* ``{"v": 2, "type": "error", "message": "..."}`` for anything malformed or larger than
  :data:`MAX_MESSAGE_BYTES` (nothing changes);
* ``{"v": 2, "type": "status", ...}`` about ten times a second (the loop's status).

Unknown keys are ignored (forward compatibility); wrong types, values out of range, unknown
channels, events or message types and any other version are errors.

Version 2 added ``viewer``, the ``"phone-ar"`` device, ``control`` in acks and the size limit.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

from kinder_gym.teleop.inputs import Pose

VERSION = 2
MAX_MESSAGE_BYTES = 16 * 1024
"""Largest message (UTF-8 bytes) parsed; an AR input message is about 300 bytes."""
CHANNELS = ("arm", "base", "gripper")
POSE_CHANNELS = ("arm", "base")
DEVICES = ("phone", "phone-ar", "xr", "script")
WEB_EVENTS = ("save", "discard", "reset")


class ProtocolError(ValueError):
    """A malformed message; the text says what was wrong and what was expected."""


@dataclasses.dataclass(frozen=True)
class InputMessage:
    seq: int
    sent: float | None
    device: str
    engaged: frozenset[str]
    poses: dict[str, Pose]
    gripper: float | None
    viewer: Pose | None = None
    """The AR session's raw viewer pose (``grab`` unused), or ``None``."""


@dataclasses.dataclass(frozen=True)
class EventMessage:
    name: str


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProtocolError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _vector(value: Any, n: int, what: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != n:
        raise ProtocolError(f"{what} must be a list of {n} numbers, got {value!r}")
    return tuple(_number(v, f"{what}[{i}]") for i, v in enumerate(value))


def _pose(value: Any, what: str) -> Pose:
    if not isinstance(value, dict):
        raise ProtocolError(f"{what} must be an object with p and q, got {value!r}")
    p = _vector(value.get("p"), 3, f"{what}.p")
    q = _vector(value.get("q", [0.0, 0.0, 0.0, 1.0]), 4, f"{what}.q")
    norm = math.sqrt(sum(c * c for c in q))
    if abs(norm - 1.0) > 1e-2:
        raise ProtocolError(f"{what}.q must be a unit quaternion, got norm {norm:.4f}")
    qn = tuple(c / norm for c in q)
    grab = value.get("grab", 0)
    if isinstance(grab, bool) or not isinstance(grab, int) or grab < 0:
        raise ProtocolError(f"{what}.grab must be a non-negative integer, got {grab!r}")
    return Pose((p[0], p[1], p[2]), (qn[0], qn[1], qn[2], qn[3]), grab)


def parse_message(text: str | bytes) -> InputMessage | EventMessage:
    """Parse and validate one client message (raises :class:`ProtocolError`)."""
    size = len(text) if isinstance(text, bytes) else len(text.encode("utf-8", errors="replace"))
    if size > MAX_MESSAGE_BYTES:
        raise ProtocolError(
            f"message of {size} bytes is larger than the limit of {MAX_MESSAGE_BYTES} bytes"
        )
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ProtocolError(f"not valid JSON: {e}") from None
    if not isinstance(data, dict):
        raise ProtocolError(f"a message must be a JSON object, got {type(data).__name__}")
    if data.get("v") != VERSION:
        raise ProtocolError(f"unsupported protocol version {data.get('v')!r}; expected {VERSION}")
    kind = data.get("type")
    if kind == "event":
        name = data.get("name")
        if name not in WEB_EVENTS:
            raise ProtocolError(f"unknown event {name!r}; expected one of {list(WEB_EVENTS)}")
        return EventMessage(str(name))
    if kind != "input":
        raise ProtocolError(f"unknown message type {kind!r}; expected 'input' or 'event'")
    seq = data.get("seq")
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        raise ProtocolError(f"seq must be a non-negative integer, got {seq!r}")
    sent = data.get("sent")
    sent_ms = None if sent is None else _number(sent, "sent")
    device = data.get("device", "script")
    if device not in DEVICES:
        raise ProtocolError(f"unknown device {device!r}; expected one of {list(DEVICES)}")
    engaged_raw = data.get("engaged", [])
    if not isinstance(engaged_raw, list) or any(c not in CHANNELS for c in engaged_raw):
        raise ProtocolError(f"engaged must be a list of {list(CHANNELS)}, got {engaged_raw!r}")
    poses_raw = data.get("poses", {})
    if not isinstance(poses_raw, dict):
        raise ProtocolError(f"poses must be an object, got {poses_raw!r}")
    poses = {}
    for channel, value in poses_raw.items():
        if channel not in POSE_CHANNELS:
            raise ProtocolError(f"unknown pose channel {channel!r}; expected {list(POSE_CHANNELS)}")
        poses[channel] = _pose(value, f"poses.{channel}")
    viewer = None
    if data.get("viewer") is not None:
        if poses:
            raise ProtocolError("a message carries either viewer or poses, not both")
        viewer = _pose(data["viewer"], "viewer")
        driven = [c for c in engaged_raw if c in POSE_CHANNELS]
        if len(driven) > 1:
            raise ProtocolError(
                f"a viewer pose drives one channel at a time; engaged names {driven}"
            )
    gripper = data.get("gripper")
    grip = None
    if gripper is not None:
        grip = _number(gripper, "gripper")
        if not 0.0 <= grip <= 1.0:
            raise ProtocolError(f"gripper must be in [0, 1], got {grip}")
    return InputMessage(seq, sent_ms, str(device), frozenset(engaged_raw), poses, grip, viewer)
