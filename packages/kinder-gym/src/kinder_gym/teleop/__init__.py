"""Teleoperation: collect KinDER demonstrations by hand (``kinder teleop``).

Three layers, each testable alone:

* **devices** (:mod:`.devices`, :mod:`.web.server`) turn an event stream (pygame events, WebSocket
  messages, a script) into plain :class:`~.inputs.InputState` snapshots;
* **mappers** (:mod:`.mappers` for the 2D robots, :mod:`.mapper3d` for the 3D mobile
  manipulator) turn a snapshot into a clipped env action and episode events;
* the **teleop loop** (:mod:`.loop`) steps the env at a fixed rate with an injectable clock and owns
  the deadman, the episode events and the recorder
  (:class:`~kinder_gym.demos.record.EpisodeRecorder`).

Front ends: :mod:`.gui2d` (pygame window for 2D, and the 3D keyboard/gamepad fallback) and
:mod:`.web` (FastAPI + WebSocket page for phones — moved in an AR session or driven by touch
pads — and WebXR headsets), chosen per env by
:mod:`.app` (what ``kinder teleop`` runs). :mod:`.saving` writes each saved episode as an atomic
file and appends them to a LeRobot dataset. The front ends need the ``teleop`` extra
(``pip install "kinder-gym[teleop]"``; 3D also ``[3d]``); this package's import pulls none of
them.
"""

import os

from kinder_gym.teleop.inputs import EPISODE_EVENTS, InputState, Pose

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # before any pygame import

__all__ = ["EPISODE_EVENTS", "InputState", "Pose"]
