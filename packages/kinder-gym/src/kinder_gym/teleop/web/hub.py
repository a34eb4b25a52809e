"""The bridge between WebSocket connections and the teleop loop (thread-safe, no web library).

:class:`WebHub` is the web app's *device*: connections hand it message text
(:meth:`WebHub.handle_text`), the loop polls it (:meth:`WebHub.poll`) for one
:class:`~kinder_gym.teleop.inputs.InputState` per tick. Per channel it keeps only the newest
sample (pages send at display rate; the loop runs at its own fixed rate).

Control, per clutch channel (``"arm"``, which carries the gripper, and ``"base"``), in
TidyBot++'s manner:

* a connection takes a free channel only after ``claim_after`` consecutive messages engaging it
  (pose updates of a phone lag its touch events, so the first messages of a grab are not used);
  it holds the channel while it keeps it engaged, and a release, a disconnect or a stale sample
  frees it. So one phone may drive the arm while a second drives the base, each with its own
  clutch; a connection that asks for a channel another one holds gets ``dropped`` with reason
  ``not_in_control``, and every other client only watches. Episode events are taken from a
  connection that holds a channel, or from anyone while nobody does;
* grab numbers are the hub's own (one per channel grab of one connection), so a channel passing
  from one device to another always re-captures the robot's reference;
* an AR phone's raw viewer pose becomes the channel's motion since the grab here
  (:class:`~kinder_gym.teleop.web.viewer.ViewerClutch`: the first message that has control
  captures the reference; a release, a mode switch or a loss of control ends the grab, and
  taking the channel again captures a new reference). Devices that number their own grabs (touch
  pads, headset grips) must grab again after a loss of control (the mapper never resumes an
  interrupted grab).

Safety rules, all judged on the **server's** clock:

* a sample older than ``max_age`` when the loop polls counts as released (deadman): the robot
  holds still until fresh input arrives (and, as after any interruption, a new grab);
* a message whose transit took ``max_age`` longer than the fastest message of its connection is
  dropped as stale (the client's clock is only compared with itself: its offset to the server's
  clock is estimated from the fastest message, so unsynchronised clocks do not matter);
* messages whose ``seq`` is not larger than the last accepted one are dropped (out of order);
* messages larger than :data:`~kinder_gym.teleop.web.protocol.MAX_MESSAGE_BYTES` and malformed
  ones get an error reply and change nothing.
"""

from __future__ import annotations

import dataclasses
import itertools
import threading
import time
from collections.abc import Callable
from typing import Any

from kinder_gym.teleop.inputs import InputState, Pose
from kinder_gym.teleop.web.protocol import (
    POSE_CHANNELS,
    VERSION,
    EventMessage,
    InputMessage,
    ProtocolError,
    parse_message,
)
from kinder_gym.teleop.web.viewer import DEFAULT_CENTRE_OFFSET, Vec3, ViewerClutch

#: Consecutive engaged messages before a connection takes a free channel (TidyBot++: "> 2").
CLAIM_AFTER = 3
#: The engaged names that belong to each controlled channel.
CHANNEL_NAMES = {"arm": frozenset({"arm", "gripper"}), "base": frozenset({"base"})}


@dataclasses.dataclass
class _Connection:
    offset: Vec3
    last_seq: int = -1
    min_offset_ms: float | None = None
    streak: dict[str, int] = dataclasses.field(
        default_factory=lambda: dict.fromkeys(POSE_CHANNELS, 0)
    )
    viewer: dict[str, ViewerClutch] = dataclasses.field(default_factory=dict)

    def clutch(self, channel: str) -> ViewerClutch:
        if channel not in self.viewer:
            self.viewer[channel] = ViewerClutch(self.offset)
        return self.viewer[channel]


@dataclasses.dataclass
class _Held:
    """The newest sample of one channel from the connection that controls it."""

    cid: int
    names: frozenset[str]
    """The channel's engaged names in that sample (empty: released)."""
    pose: Pose | None
    gripper: float | None
    time: float
    fresh: bool = True


class WebHub:
    """See the module docstring.

    Args:
        max_age: Seconds after which a sample (or a message's extra transit) is stale.
        clock: The loop's clock (``time.perf_counter`` by default; tests inject a fake one).
        claim_after: Consecutive engaged messages before a connection takes a free channel.
        centre_offset: The AR phone's centre seen from its camera (camera axes, metres).
    """

    def __init__(
        self,
        max_age: float = 0.25,
        clock: Callable[[], float] | None = None,
        claim_after: int = CLAIM_AFTER,
        centre_offset: Vec3 = DEFAULT_CENTRE_OFFSET,
    ) -> None:
        if claim_after < 1:
            raise ValueError(f"claim_after must be at least 1, got {claim_after}")
        self.max_age = float(max_age)
        self.clock = clock or time.perf_counter
        self.claim_after = int(claim_after)
        self.centre_offset = centre_offset
        self._lock = threading.Lock()
        self._ids = itertools.count(1)
        self._grab_ids = itertools.count(1)
        self._connections: dict[int, _Connection] = {}
        self._held: dict[str, _Held] = {}
        self._grabs: dict[str, dict[tuple[int, int], int]] = {}
        self._events: set[str] = set()
        self._status: dict[str, Any] = {}
        self._frames: dict[str, bytes] = {}
        self.received = 0
        self.dropped = 0
        self.frames_set = 0

    # -- connections -----------------------------------------------------------------------------
    def connect(self) -> int:
        with self._lock:
            cid = next(self._ids)
            self._connections[cid] = _Connection(self.centre_offset)
            return cid

    def disconnect(self, cid: int) -> None:
        with self._lock:
            self._connections.pop(cid, None)
            for channel in [c for c, held in self._held.items() if held.cid == cid]:
                del self._held[channel]

    def _owner(self, channel: str, now: float) -> int | None:
        held = self._held.get(channel)
        if held is None or not held.names or now - held.time > self.max_age:
            return None
        return held.cid

    def controls(self, cid: int) -> list[str]:
        """The channels connection ``cid`` controls now."""
        with self._lock:
            now = self.clock()
            return [c for c in POSE_CHANNELS if self._owner(c, now) == cid]

    def _grab(self, channel: str, cid: int, client_grab: int) -> int:
        """The hub's grab number for grab ``client_grab`` of connection ``cid`` (the same one
        every time, so a grab that lost the channel and takes it back is still the interrupted
        grab, which the mapper does not resume)."""
        known = self._grabs.setdefault(channel, {})
        return known.setdefault((cid, client_grab), next(self._grab_ids))

    def handle_text(self, cid: int, text: str | bytes) -> dict[str, Any]:
        """Handle one message of connection ``cid``; returns the reply to send."""
        now = self.clock()
        try:
            message = parse_message(text)
        except ProtocolError as e:
            return {"v": VERSION, "type": "error", "message": str(e)}
        with self._lock:
            conn = self._connections.get(cid)
            if conn is None:
                return {"v": VERSION, "type": "error", "message": "unknown connection"}
            if isinstance(message, EventMessage):
                owners = {self._owner(c, now) for c in POSE_CHANNELS} - {None}
                if owners and cid not in owners:
                    self.dropped += 1
                    return {
                        "v": VERSION,
                        "type": "dropped",
                        "name": message.name,
                        "reason": "not_in_control",
                    }
                self._events.add(message.name)
                return {"v": VERSION, "type": "event_ack", "name": message.name}
            seq = message.seq
            if seq <= conn.last_seq:
                self.dropped += 1
                return {"v": VERSION, "type": "dropped", "seq": seq, "reason": "out_of_order"}
            if message.sent is not None:
                offset = now * 1000.0 - message.sent
                if conn.min_offset_ms is None or offset < conn.min_offset_ms:
                    conn.min_offset_ms = offset
                if offset - conn.min_offset_ms > self.max_age * 1000.0:
                    self.dropped += 1
                    return {"v": VERSION, "type": "dropped", "seq": seq, "reason": "stale"}
            conn.last_seq = seq
            denied = self._apply(cid, conn, message, now)
            control = [c for c in POSE_CHANNELS if self._owner(c, now) == cid]
            if denied and not control:
                self.dropped += 1
                return {"v": VERSION, "type": "dropped", "seq": seq, "reason": "not_in_control"}
            self.received += 1
            return {"v": VERSION, "type": "ack", "seq": seq, "control": control}

    def _apply(self, cid: int, conn: _Connection, message: InputMessage, now: float) -> bool:
        """Update the channels ``cid`` controls (or claims) from ``message``; returns whether it
        asked for a channel another connection holds."""
        denied = False
        for channel in POSE_CHANNELS:
            names = message.engaged & CHANNEL_NAMES[channel]
            conn.streak[channel] = conn.streak[channel] + 1 if names else 0
            owner = self._owner(channel, now)
            drives = channel in message.engaged
            if owner not in (None, cid) or (owner is None and not names):
                denied = denied or (owner is not None and bool(names))
                conn.clutch(channel).release()
                continue
            if owner is None:
                if conn.streak[channel] < self.claim_after:
                    continue  # claiming: not yet in control
                # Taking (or, after stale samples, retaking) the channel starts a new grab: an AR
                # phone's reference is captured again here, so its motion resumes without a jump.
                conn.clutch(channel).release()
            pose = None
            if not drives:
                conn.clutch(channel).release()
            elif message.viewer is not None:
                clutch = conn.clutch(channel)
                motion = clutch.update(message.viewer.p, message.viewer.q)
                pose = Pose(motion.p, motion.q, self._grab(channel, cid, motion.grab))
            elif channel in message.poses:
                sent = message.poses[channel]
                pose = Pose(sent.p, sent.q, self._grab(channel, cid, sent.grab))
            gripper = message.gripper if channel == "arm" else None
            self._held[channel] = _Held(cid, names, pose, gripper, now)
        return denied

    # -- the loop side --------------------------------------------------------------------------
    def poll(self, now: float) -> InputState:
        """The input state for one loop tick (the device interface): the engaged channels'
        newest samples, each from the connection that controls it."""
        with self._lock:
            pressed = frozenset(f"event_{name}" for name in self._events)
            self._events.clear()
            poses: dict[str, Pose] = {}
            engaged: set[str] = set()
            scalars: dict[str, float] = {}
            received: float | None = None
            for channel, held in self._held.items():
                if not held.names or now - held.time > self.max_age:
                    continue
                engaged |= held.names
                if held.pose is not None:
                    poses[channel] = held.pose
                if held.gripper is not None:
                    scalars["gripper"] = held.gripper
                if held.fresh:
                    received = held.time if received is None else max(received, held.time)
                    held.fresh = False
            return InputState(
                t=now,
                source="web",
                enabled=bool(engaged),
                pressed=pressed,
                poses=poses,
                engaged=frozenset(engaged),
                scalars=scalars,
                received=received,
            )

    def set_status(self, status: dict[str, Any]) -> None:
        with self._lock:
            self._status = status

    def status(self) -> dict[str, Any]:
        with self._lock:
            return {"v": VERSION, "type": "status", **self._status}

    def set_frames(self, frames: dict[str, bytes]) -> None:
        with self._lock:
            self._frames = dict(frames)
            self.frames_set += 1

    def camera_names(self) -> list[str]:
        """The cameras that have a frame."""
        with self._lock:
            return sorted(self._frames)

    def frame(self, camera: str) -> bytes | None:
        with self._lock:
            return self._frames.get(camera)
