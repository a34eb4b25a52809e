"""The teleop loop: a fixed-rate env loop that owns the deadman, the episode events and the
recorder.

Every tick (``hz`` per second of the injected :class:`Clock`) the loop takes one input snapshot
from the device (``poll(now)``), asks the mapper for an action and **steps the env whether or not
an input changed** (a held key keeps moving the robot; Dynamic2D physics keep running while the
operator is idle). When the deadman is released (the mapper returns ``None``) the robot is
paused: no step and nothing recorded, so a paused episode replays exactly.

Episodes: a reset starts recording (seed ``seed``, then ``seed + 1`` … for each new episode).
``auto_save`` saves a successful episode (``terminated``) the step it succeeds; a truncated
episode is discarded. The events ``save`` (save now, success or not), ``discard`` (drop it),
``reset`` (drop it and restart the same seed) and ``quit`` come from the bindings. Save and
discard move on to the next seed. Saving goes through the injected ``save`` callback (one
:class:`~kinder_gym.demos.record.EpisodeRecord` each; empty episodes are never saved), so storage
is the caller's choice; the ``kinder teleop`` command writes LeRobot datasets.
"""

from __future__ import annotations

import collections
import dataclasses
import time
from collections.abc import Callable
from typing import Any, Protocol

import gymnasium
import numpy as np

from kinder_gym.demos.record import EpisodeRecord, EpisodeRecorder
from kinder_gym.teleop.inputs import InputState
from kinder_gym.teleop.mappers import MapOutput, Mapper


class Clock(Protocol):
    """Time source of the loop (seconds); tests inject :class:`FakeClock`."""

    def now(self) -> float: ...

    def sleep_until(self, t: float) -> None: ...


class WallClock:
    """``time.perf_counter`` and real sleeping."""

    def now(self) -> float:
        return time.perf_counter()

    def sleep_until(self, t: float) -> None:
        delay = t - time.perf_counter()
        if delay > 0:
            time.sleep(delay)


class FakeClock:
    """A clock that only moves when slept on (deterministic tests)."""

    def __init__(self, start: float = 0.0) -> None:
        self.t = start

    def now(self) -> float:
        return self.t

    def sleep_until(self, t: float) -> None:
        self.t = max(self.t, t)


@dataclasses.dataclass
class TeleopStatus:
    """What the displays show (the status line, the web page's status message)."""

    env_id: str
    seed: int
    step: int = 0
    success: bool = False
    recording: bool = False
    paused: bool = False
    episodes_saved: int = 0
    episodes_discarded: int = 0
    message: str = ""
    info: dict[str, Any] = dataclasses.field(default_factory=dict)

    def line(self) -> str:
        state = "PAUSED" if self.paused else ("REC" if self.recording else "ready")
        parts = [
            self.env_id,
            f"seed {self.seed}",
            f"step {self.step}",
            "SUCCESS" if self.success else "not solved",
            state,
            f"saved {self.episodes_saved}",
        ]
        if self.message:
            parts.append(self.message)
        return " | ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        data["info"] = {k: v for k, v in self.info.items() if _jsonable(v)}
        return data


def _jsonable(value: Any) -> bool:
    return isinstance(value, (bool, int, float, str, list, tuple)) or value is None


class TeleopLoop:
    """The fixed-rate teleop loop (module docstring).

    Args:
        env: The env (Box view, from ``kinder_core.make``).
        env_id: Its registered id (recorded).
        mapper: Input → action (:mod:`kinder_gym.teleop.mappers`, :mod:`.mapper3d`).
        poll: The device: ``poll(now) -> InputState``; must not block.
        save: Called with every episode to keep; ``None`` keeps them in :attr:`saved` only.
        seed: Seed of the first episode.
        hz: Control rate (ticks per second).
        clock: Time source (default :class:`WallClock`).
        auto_save: Save successful episodes automatically.
        metadata: Extra metadata stored in every record (device, bindings, …).
    """

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        env_id: str,
        mapper: Mapper,
        poll: Callable[[float], InputState],
        *,
        save: Callable[[EpisodeRecord], object] | None = None,
        seed: int = 0,
        hz: float = 20.0,
        clock: Clock | None = None,
        auto_save: bool = True,
        metadata: dict[str, Any] | None = None,
    ) -> None:
        if not hz > 0:
            raise ValueError(f"hz must be positive, got {hz}")
        self.env = env
        self.env_id = env_id
        self.mapper = mapper
        self.poll = poll
        self.save_fn = save
        self.hz = float(hz)
        self.clock: Clock = clock or WallClock()
        self.auto_save = auto_save
        self.metadata = dict(metadata or {})
        self.recorder = EpisodeRecorder(env, env_id, "teleop")
        self.saved: list[EpisodeRecord] = []
        self.status = TeleopStatus(env_id=env_id, seed=seed)
        self.quit = False
        self.ticks = 0
        self.total_steps = 0
        """Env steps over every episode of this loop."""
        self.last_output: MapOutput | None = None
        #: Seconds from a remote message's arrival to its action being applied (recent ones).
        self.latencies: collections.deque[float] = collections.deque(maxlen=10_000)
        self.on_episode_start: list[Callable[[], None]] = []
        self.reset(seed)

    # -- episodes -------------------------------------------------------------------------------
    def reset(self, seed: int) -> None:
        """Start recording a new episode from ``seed``."""
        self.recorder.reset(seed)
        self.mapper.reset(self.env)
        self.status.seed = seed
        self.status.step = 0
        self.status.success = False
        self.status.recording = False
        for callback in self.on_episode_start:
            callback()

    def _record(self, note: str) -> EpisodeRecord:
        meta = {"teleop_hz": self.hz, "end": note, **self.metadata}
        from kinder_gym.demos.lerobot_format import env_task

        return self.recorder.finish(task=env_task(self.env), metadata=meta)

    def save_episode(self, note: str = "manual") -> EpisodeRecord | None:
        """Save the current episode and move on to the next seed; an episode without steps is
        not saved and stays current."""
        if self.recorder.num_steps == 0:
            self.status.message = "nothing to save yet (no steps)"
            return None
        record = self._record(note)
        self.saved.append(record)
        if self.save_fn is not None:
            self.save_fn(record)
        self.status.episodes_saved += 1
        self.status.message = f"saved seed {record.seed} ({record.num_steps} steps, {note})"
        self.reset(self.status.seed + 1)
        return record

    def discard_episode(self, same_seed: bool = False, why: str = "discarded") -> None:
        """Drop the current episode; restart the same seed or go to the next one."""
        if self.recorder.num_steps > 0:
            self.status.episodes_discarded += 1
        self.status.message = f"{why} seed {self.status.seed}"
        self.reset(self.status.seed if same_seed else self.status.seed + 1)

    # -- the loop -------------------------------------------------------------------------------
    def tick(self) -> TeleopStatus:
        """One control tick: poll, map, handle events, step (unless paused)."""
        now = self.clock.now()
        state = self.poll(now)
        out = self.mapper(state, self.env)
        self.last_output = out
        self.ticks += 1
        self.status.info = dict(out.info)
        events = out.events
        if "quit" in events:
            self.quit = True
            return self.status
        if "reset" in events:
            self.discard_episode(same_seed=True, why="restarted")
            return self.status
        if "discard" in events:
            self.discard_episode()
            return self.status
        if "save" in events:
            self.save_episode("manual")
            return self.status
        self.status.paused = out.action is None
        if out.action is None:
            return self.status
        _, _, terminated, truncated, _ = self.recorder.step(out.action)
        self.total_steps += 1
        if state.received is not None:
            self.latencies.append(self.clock.now() - state.received)
        self.status.step = self.recorder.num_steps
        self.status.recording = True
        self.status.success = terminated
        if terminated and self.auto_save:
            self.save_episode("success")
        elif terminated or truncated:
            self.discard_episode(why="truncated" if truncated else "ended (auto-save off)")
        return self.status

    def run(
        self, max_ticks: int | None = None, after_tick: Callable[[], None] | None = None
    ) -> None:
        """Tick at ``hz`` until ``quit`` (or ``max_ticks``); ``after_tick`` draws the display."""
        period = 1.0 / self.hz
        next_tick = self.clock.now()
        count = 0
        while not self.quit and (max_ticks is None or count < max_ticks):
            self.tick()
            if after_tick is not None:
                after_tick()
            count += 1
            next_tick += period
            now = self.clock.now()
            if next_tick < now - period:  # fell behind by more than a tick: do not burst
                next_tick = now
            self.clock.sleep_until(next_tick)


def latency_summary(latencies: collections.deque[float] | list[float]) -> dict[str, float]:
    """Mean, median, 95th percentile and max (milliseconds) of message→action latencies."""
    values = np.asarray(list(latencies), dtype=np.float64) * 1000.0
    if values.size == 0:
        return {"n": 0.0}
    return {
        "n": float(values.size),
        "mean_ms": float(values.mean()),
        "p50_ms": float(np.percentile(values, 50)),
        "p95_ms": float(np.percentile(values, 95)),
        "max_ms": float(values.max()),
    }
