"""The device-agnostic input snapshot every device produces and every mapper reads.

A device turns its own event stream (pygame events, WebSocket messages, a test script) into one
:class:`InputState` per control tick. Names are plain strings so that a mapper, a test or a log
line never needs the device's library:

* ``buttons``: what is held now; ``pressed``: what went down since the previous snapshot (rising
  edges, so a tap shorter than a tick is never lost). Keyboard keys use pygame's key names
  (``"w"``, ``"space"``, ``"return"``, ``"left ctrl"``); gamepad buttons are ``"pad_<name>"``
  with SDL GameController names (``pad_a`` is the bottom face button: Cross on a DualSense);
  web events are ``"event_<name>"``.
* ``axes``: values in [−1, 1], y axes positive *up*: ``pad_lx``, ``pad_ly``, ``pad_rx``,
  ``pad_ry``, ``pad_lt``, ``pad_rt`` (triggers, 0 … 1) and the on-screen mouse sticks
  ``mouse_lx`` … ``mouse_ry``.
* ``poses``: clutch channels of the web app (``"arm"``, ``"base"``), each the device's motion
  since the current grab began, a :class:`Pose` in the WebXR frame (+x right, +y up, +z towards
  the user); ``engaged`` names the channels whose clutch (finger or grip) is held now.
* ``scalars``: e.g. ``"gripper"`` in [0, 1] (1 = closed) from the phone slider or the XR trigger.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

#: Names of the episode events every device may emit (mappers translate bindings into these).
EPISODE_EVENTS = ("save", "discard", "reset", "next", "quit")


@dataclasses.dataclass(frozen=True)
class Pose:
    """A rigid pose: position ``p`` (m) and unit quaternion ``q`` ordered (x, y, z, w).

    For clutch channels it is the device's motion since the grab numbered ``grab`` began (the
    device computes it, so a grab is anchored where the finger or grip went down however late its
    first message arrives); a new ``grab`` number re-captures the robot's reference."""

    p: tuple[float, float, float]
    q: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    grab: int = 0


@dataclasses.dataclass(frozen=True)
class InputState:
    """One snapshot of a device's input (see the module docstring for the names)."""

    t: float
    """The control loop's clock when the snapshot was taken (never a remote device's clock)."""
    source: str
    """Which device produced it: ``"keyboard"``, ``"gamepad"``, ``"web"``, ``"script"``."""
    enabled: bool = True
    """The deadman: ``False`` pauses the robot (no step, nothing recorded)."""
    buttons: frozenset[str] = frozenset()
    pressed: frozenset[str] = frozenset()
    axes: Mapping[str, float] = dataclasses.field(default_factory=dict)
    poses: Mapping[str, Pose] = dataclasses.field(default_factory=dict)
    engaged: frozenset[str] = frozenset()
    scalars: Mapping[str, float] = dataclasses.field(default_factory=dict)
    received: float | None = None
    """For remote devices: the loop-clock time the newest message arrived (for latency)."""

    def axis(self, name: str) -> float:
        """The value of axis ``name`` (0 when the device has no such axis)."""
        return float(self.axes.get(name, 0.0))
