"""Camera frames for the web page, rendered off the control loop.

Rendering every camera of a 3D env costs tens to hundreds of milliseconds on a CPU (pybullet's
software renderer, MuJoCo's offscreen context), more than a 10 Hz control tick. In the loop thread
it would throttle control, and a render thread would still hold the GIL, so :class:`FrameWorker`
renders in a separate process with its own env instance: the loop hands it the newest
object-centric state whenever the worker is idle (never waiting), and picks up the JPEGs when
they are ready. The page therefore shows frames at whatever rate the machine can render, while
control keeps its rate.
"""

from __future__ import annotations

import contextlib
import io
import multiprocessing
import signal
import sys
import threading
from multiprocessing.connection import Connection
from typing import Any

import gymnasium
import numpy as np


def encode_jpeg(image: np.ndarray[Any, Any], quality: int = 80) -> bytes:
    """JPEG bytes of an H×W×3 uint8 image."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image[:, :, :3])).save(buffer, "JPEG", quality=quality)
    return buffer.getvalue()


def set_image_size(env: gymnasium.Env[Any, Any], width: int, height: int) -> None:
    """Shrink a 3D env's rendered frames (its ``config`` dataclass's ``image_width``/
    ``image_height``); envs without them keep their size."""
    import dataclasses

    model = env.unwrapped
    config = getattr(model, "config", None)
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        names = {f.name for f in dataclasses.fields(config)}
        if {"image_width", "image_height"} <= names:
            new = dataclasses.replace(config, image_width=width, image_height=height)
            model.config = new  # type: ignore[attr-defined]


def render_views(
    env: gymnasium.Env[Any, Any], state: Any = None
) -> dict[str, np.ndarray[Any, Any]]:
    """Every camera of a 3D env (``render_cameras``), else the env's single rendering."""
    model = env.unwrapped
    cameras = getattr(model, "render_cameras", None)
    if callable(cameras):
        return {str(k): np.asarray(v) for k, v in cameras(state).items()}
    return {"view": np.asarray(env.render())}


def jpeg_views(env: gymnasium.Env[Any, Any], state: Any = None) -> dict[str, bytes]:
    return {name: encode_jpeg(img) for name, img in render_views(env, state).items()}


def _worker(env_id: str, size: tuple[int, int], conn: Connection) -> None:
    # Ctrl+C reaches the whole process group: the parent decides when to stop (it sends None);
    # SIGTERM or a parent that is gone end the worker quietly instead of with a traceback.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(0))
    import kinder_core

    env = kinder_core.make(env_id, render_mode="rgb_array")
    set_image_size(env, *size)
    seed = None
    try:
        while True:
            job = conn.recv()
            if job is None:
                break
            job_seed, state = job
            if job_seed != seed:  # scenes may depend on the episode's seed
                env.reset(seed=job_seed)
                seed = job_seed
            conn.send(jpeg_views(env, state))
    except (EOFError, OSError):  # the parent is gone (BrokenPipeError is an OSError)
        pass
    finally:
        env.close()


class FrameWorker:
    """Renders JPEG camera views of submitted states in a separate process (module docstring)."""

    def __init__(self, env_id: str, size: tuple[int, int]) -> None:
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(target=_worker, args=(env_id, size, child), daemon=True)
        # The child inherits an ignored SIGINT from its first instruction on, so a Ctrl+C while
        # it is still importing cannot interrupt it either (signals only in the main thread).
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            self._proc.start()
        finally:
            if main:
                signal.signal(signal.SIGINT, previous)
        self._busy = False
        self.ended = False
        """Whether the worker process has gone (killed, crashed): no more frames."""

    def submit(self, seed: int, state: Any) -> bool:
        """Hand over a state to render if the worker is idle; returns whether it took it (never
        once the worker has ended: control goes on without frames)."""
        if self._busy or self.ended:
            return False
        try:
            self._conn.send((seed, state))
        except OSError:
            self.ended = True
            return False
        self._busy = True
        return True

    def poll(self) -> dict[str, bytes] | None:
        """The finished frames, if any (never blocks)."""
        if not self._busy or self.ended:
            return None
        try:
            if not self._conn.poll():
                return None
            frames: dict[str, bytes] = self._conn.recv()
        except (EOFError, OSError):
            self.ended = True
            return None
        self._busy = False
        return frames

    def close(self) -> None:
        with contextlib.suppress(BrokenPipeError, OSError):
            self._conn.send(None)
        self._proc.join(timeout=5.0)
        if self._proc.is_alive():
            self._proc.terminate()
