"""The bridge between WebSocket connections and the teleop loop (thread-safe, no web library).

:class:`WebHub` is the web app's *device*: connections hand it message text
(:meth:`WebHub.handle_text`), the loop polls it (:meth:`WebHub.poll`) for one
:class:`~kinder_gym.teleop.inputs.InputState` per tick. It keeps only the newest input sample
(the page sends at display rate; the loop runs at its own fixed rate).

Safety rules, all judged on the **server's** clock:

* a sample older than ``max_age`` when the loop polls counts as released (deadman): the robot
  holds still until fresh input arrives;
* a message whose transit took ``max_age`` longer than the fastest message of its connection is
  dropped as stale (the client's clock is only compared with itself: its offset to the server's
  clock is estimated from the fastest message, so unsynchronised clocks do not matter);
* messages whose ``seq`` is not larger than the last accepted one are dropped (out of order);
* one connection is in control at a time (the first to send input); others get ``dropped``
  with reason ``not_in_control`` until it disconnects. A disconnect releases everything.
"""

from __future__ import annotations

import dataclasses
import itertools
import threading
import time
from collections.abc import Callable
from typing import Any

from kinder_gym.teleop.inputs import InputState
from kinder_gym.teleop.web.protocol import (
    VERSION,
    EventMessage,
    InputMessage,
    ProtocolError,
    parse_message,
)


@dataclasses.dataclass
class _Connection:
    last_seq: int = -1
    min_offset_ms: float | None = None


class WebHub:
    """See the module docstring.

    Args:
        max_age: Seconds after which a sample (or a message's extra transit) is stale.
        clock: The loop's clock (``time.perf_counter`` by default; tests inject a fake one).
    """

    def __init__(self, max_age: float = 0.25, clock: Callable[[], float] | None = None) -> None:
        self.max_age = float(max_age)
        self.clock = clock or time.perf_counter
        self._lock = threading.Lock()
        self._ids = itertools.count(1)
        self._connections: dict[int, _Connection] = {}
        self._controller: int | None = None
        self._sample: InputMessage | None = None
        self._sample_time = 0.0
        self._sample_fresh = False
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
            self._connections[cid] = _Connection()
            return cid

    def disconnect(self, cid: int) -> None:
        with self._lock:
            self._connections.pop(cid, None)
            if self._controller == cid:
                self._controller = None
                self._sample = None

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
                self._events.add(message.name)
                return {"v": VERSION, "type": "event_ack", "name": message.name}
            seq = message.seq
            if self._controller not in (None, cid):
                self.dropped += 1
                return {"v": VERSION, "type": "dropped", "seq": seq, "reason": "not_in_control"}
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
            self._controller = cid
            self._sample = message
            self._sample_time = now
            self._sample_fresh = True
            self.received += 1
            return {"v": VERSION, "type": "ack", "seq": seq}

    # -- the loop side --------------------------------------------------------------------------
    def poll(self, now: float) -> InputState:
        """The input state for one loop tick (the device interface)."""
        with self._lock:
            pressed = frozenset(f"event_{name}" for name in self._events)
            self._events.clear()
            sample = self._sample
            if sample is None or now - self._sample_time > self.max_age:
                return InputState(t=now, source="web", enabled=False, pressed=pressed)
            received = self._sample_time if self._sample_fresh else None
            self._sample_fresh = False
            scalars = {} if sample.gripper is None else {"gripper": sample.gripper}
            return InputState(
                t=now,
                source="web",
                enabled=bool(sample.engaged),
                pressed=pressed,
                poses=dict(sample.poses),
                engaged=sample.engaged,
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
