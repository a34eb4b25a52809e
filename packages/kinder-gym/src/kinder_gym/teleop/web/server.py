"""The 3D teleop web app: FastAPI serves one self-contained page, a WebSocket and camera frames.

``kinder teleop kinder/<3D id> --web`` runs :func:`serve`: a :class:`WebTeleop` (env, 3D mapper,
:class:`~kinder_gym.teleop.web.hub.WebHub`, teleop loop) in the main thread and uvicorn in a
background thread. It prints the URL (with a random session token) and a QR code of it.

Routes (every one needs ``?token=<session token>``; a wrong token gets 403 / close code 1008):

* ``GET /`` — the page (``static/index.html``: no external assets, plain WebSocket, Pointer
  Events). Phone with WebXR AR ("Move the phone (AR)", an ``immersive-ar`` session): the
  phone's raw viewer pose is sent every XR frame; holding the arm zone makes the hand follow
  the phone's motion 1:1, holding the base strip the base (TidyBot++'s teleop; the server
  captures the reference, :mod:`kinder_gym.teleop.web.viewer`); lifting the finger freezes the
  target; a gripper slider and Save/Discard/Restart/Exit AR buttons sit on the AR view. Where
  the browser has no AR session the page says so and offers the touch pads: an arm pad (drag =
  hand forward/left, the strip at its edge = up/down), a base pad (drag = drive, the strip at
  its bottom = turn), a gripper slider and Save/Discard/Restart buttons; motion is relative to
  where the finger went down (a clutch). WebXR headset ("Enter VR"): the left controller's grip
  drives the base, the right's the hand, each while its grip (squeeze) button is held (the
  deadman); the right trigger closes the gripper; A saves, B discards. The page shows the live
  camera views (in VR on a panel in front of the user). Several pages may connect: each channel
  (arm, base) is driven by one of them at a time (:mod:`kinder_gym.teleop.web.hub`).
* ``WS /ws`` — the protocol of :mod:`kinder_gym.teleop.web.protocol` (text or binary frames of
  at most :data:`~kinder_gym.teleop.web.protocol.MAX_MESSAGE_BYTES`; larger ones get an error
  reply, up to uvicorn's 16 MiB frame limit, beyond which it closes the connection with 1009).
* ``GET /frame/{camera}.jpg`` — the newest JPEG of a camera (rendered in a separate process
  from the loop's newest state, :mod:`kinder_gym.teleop.web.frames`); the status messages list
  the cameras that have frames.
* ``GET /status`` — the loop's status as JSON (with the measured base pose ``base`` and the
  hand's pose in the base frame ``ee``: position and quaternion x, y, z, w).

Default bind address 127.0.0.1; pass ``host="0.0.0.0"`` to reach it from a phone on the LAN.
Browsers only grant WebXR on secure origins: ``localhost`` is one, a LAN address needs HTTPS
(``ssl_certfile``/``ssl_keyfile``, e.g. a self-signed certificate). The phone's touch pads work
over plain HTTP. :func:`serve` stops cleanly on Ctrl+C or SIGTERM (after the current tick).
"""

from __future__ import annotations

import asyncio
import secrets
import signal
import threading
from collections.abc import Callable
from importlib import resources
from typing import Any

from fastapi import FastAPI, HTTPException, Query, WebSocket, WebSocketDisconnect
from fastapi.responses import HTMLResponse, JSONResponse, Response

import kinder_core
from kinder_gym.demos.record import EpisodeRecord
from kinder_gym.teleop.loop import Clock, TeleopLoop
from kinder_gym.teleop.mapper3d import Limits, TidyBotTeleop, ee_pose_in_base
from kinder_gym.teleop.web.frames import (
    FrameWorker,
    jpeg_views,
    set_image_size,
)
from kinder_gym.teleop.web.hub import CLAIM_AFTER, WebHub
from kinder_gym.teleop.web.protocol import MAX_MESSAGE_BYTES, VERSION

STATUS_PERIOD = 0.1


def page_html() -> str:
    """The page's HTML (one file, no external assets)."""
    return resources.files("kinder_gym.teleop.web").joinpath("static/index.html").read_text()


def create_app(hub: WebHub, token: str, hello: dict[str, Any] | None = None) -> FastAPI:
    """The FastAPI app around ``hub`` (routes in the module docstring)."""
    app = FastAPI(title="KinDER teleop", docs_url=None, redoc_url=None, openapi_url=None)
    hello_msg = {"v": VERSION, "type": "hello", **(hello or {})}
    expected = token

    def check(given: str) -> None:
        if not secrets.compare_digest(given, expected):
            raise HTTPException(status_code=403, detail="wrong or missing session token")

    @app.get("/")
    def index(token: str = Query("")) -> HTMLResponse:
        check(token)
        return HTMLResponse(page_html())

    @app.get("/status")
    def status(token: str = Query("")) -> JSONResponse:
        check(token)
        return JSONResponse(hub.status())

    @app.get("/frame/{camera}.jpg")
    def frame(camera: str, token: str = Query("")) -> Response:
        check(token)
        data = hub.frame(camera)
        if data is None:
            raise HTTPException(status_code=404, detail=f"no frame for camera {camera!r}")
        return Response(data, media_type="image/jpeg", headers={"Cache-Control": "no-store"})

    @app.websocket("/ws")
    async def ws(websocket: WebSocket, token: str = Query("")) -> None:
        if not secrets.compare_digest(token, expected):
            await websocket.close(code=1008)
            return
        await websocket.accept()
        cid = hub.connect()
        await websocket.send_json(hello_msg)

        async def push_status() -> None:
            while True:
                await websocket.send_json(hub.status())
                await asyncio.sleep(STATUS_PERIOD)

        pusher = asyncio.create_task(push_status())
        try:
            while True:
                message = await websocket.receive()
                if message["type"] == "websocket.disconnect":
                    break
                data = message.get("text")
                if data is None:
                    data = message.get("bytes") or b""
                await websocket.send_json(hub.handle_text(cid, data))
        except WebSocketDisconnect:
            pass
        finally:
            pusher.cancel()
            hub.disconnect(cid)

    return app


class WebTeleop:
    """The web app's back end: env + 3D mapper + hub + teleop loop + frame publishing.

    Args:
        env_id: A registered 3D id.
        seed: First episode's seed.
        save: Called with each saved episode.
        hz: Control rate.
        max_age: Staleness limit (s) of input samples.
        limits: Target rate limits of the mapper.
        frame_every: Render the cameras every this many ticks (0: never). In-thread rendering
            happens in the thread that runs the loop (MuJoCo's GL context is per thread).
        frame_process: Render in a separate process (:class:`~.frames.FrameWorker`: control
            keeps its rate; frames come as fast as they render). Otherwise render in the loop
            thread every ``frame_every`` ticks (simple and deterministic: tests), which stalls
            those ticks by the rendering time (about 70–170 ms for three 320×180 cameras).
        frame_size: Width and height of the streamed camera images (set through the env's
            ``config.image_width``/``image_height`` when it has them).
        clock: Injected clock (tests).
        token: Session token (random by default).
        auto_save: Save successful episodes automatically.
        claim_after: Consecutive engaged messages before a connection takes a free channel.
    """

    def __init__(
        self,
        env_id: str,
        *,
        seed: int = 0,
        save: Callable[[EpisodeRecord], object] | None = None,
        hz: float = 10.0,
        max_age: float = 0.25,
        limits: Limits | None = None,
        frame_every: int = 3,
        frame_size: tuple[int, int] = (320, 180),
        clock: Clock | None = None,
        token: str | None = None,
        auto_save: bool = True,
        frame_process: bool = False,
        claim_after: int = CLAIM_AFTER,
    ) -> None:
        self.env = kinder_core.make(env_id, render_mode="rgb_array")
        set_image_size(self.env, *frame_size)
        self.frame_worker = FrameWorker(env_id, frame_size) if frame_process else None
        self.mapper = TidyBotTeleop(self.env, hz=hz, limits=limits)
        self.hub = WebHub(
            max_age=max_age,
            clock=clock.now if clock is not None else None,
            claim_after=claim_after,
        )
        self.loop = TeleopLoop(
            self.env,
            env_id,
            self.mapper,
            self.hub.poll,
            save=save,
            seed=seed,
            hz=hz,
            clock=clock,
            auto_save=auto_save,
            metadata={"device": "web"},
        )
        self.token = token or secrets.token_urlsafe(12)
        self.frame_every = int(frame_every)
        # Nothing is rendered here: MuJoCo's EGL context belongs to the thread that first
        # renders, which must be the loop's (or the frame worker's) thread.
        self.publish_status()
        hello = {
            "env_id": env_id,
            "max_age_ms": max_age * 1000.0,
            "hz": hz,
            "max_message_bytes": MAX_MESSAGE_BYTES,
            "claim_after": self.hub.claim_after,
        }
        self.app = create_app(self.hub, self.token, hello)

    def publish_frames(self) -> None:
        """Render (or hand to the frame worker) the cameras' views of the live state."""
        worker = self.frame_worker
        if worker is None:
            self.hub.set_frames(jpeg_views(self.env))
            return
        frames = worker.poll()
        if frames is not None:
            self.hub.set_frames(frames)
        model = self.env.unwrapped
        assert isinstance(model, kinder_core.ObjectCentricEnv)
        worker.submit(self.loop.status.seed, model.get_state())

    def publish_status(self) -> None:
        status = self.loop.status.to_dict()
        base, arm = self.mapper.measured(self.env)
        ee_p, ee_q = ee_pose_in_base(arm)
        status["base"] = [float(v) for v in base]
        status["ee"] = [float(v) for v in (*ee_p, *ee_q)]
        status["received"] = self.hub.received
        status["dropped"] = self.hub.dropped
        status["cameras"] = self.hub.camera_names()
        self.hub.set_status(status)

    def after_tick(self) -> None:
        """Publish status every tick and frames every ``frame_every`` ticks (loop thread)."""
        if self.frame_worker is not None or (
            self.frame_every > 0 and self.loop.ticks % self.frame_every == 0
        ):
            self.publish_frames()
        self.publish_status()

    def run(self, max_ticks: int | None = None) -> None:
        self.loop.run(max_ticks=max_ticks, after_tick=self.after_tick)

    def close(self) -> None:
        if self.frame_worker is not None:
            self.frame_worker.close()
        self.env.close()


class ServerThread:
    """uvicorn serving an app from a daemon thread (``port=0`` picks a free port)."""

    def __init__(self, app: FastAPI, host: str = "127.0.0.1", port: int = 0, **ssl: Any) -> None:
        import uvicorn

        config = uvicorn.Config(app, host=host, port=port, log_level="warning", **ssl)
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, daemon=True)

    def start(self, timeout: float = 10.0) -> int:
        """Start serving; returns the bound port."""
        self.thread.start()
        for _ in range(int(timeout / 0.01)):
            if self.server.started:
                break
            threading.Event().wait(0.01)
        if not self.server.started:
            raise RuntimeError("the teleop web server did not start")
        sockets = self.server.servers[0].sockets
        return int(sockets[0].getsockname()[1])

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=5.0)


def print_url(url: str) -> None:
    """Print the URL and a terminal QR code of it."""
    import qrcode

    print(f"KinDER teleop page: {url}")
    qr = qrcode.QRCode(border=1)
    qr.add_data(url)
    qr.print_ascii(invert=True)


def serve(
    env_id: str,
    *,
    seed: int = 0,
    save: Callable[[EpisodeRecord], object] | None = None,
    hz: float = 10.0,
    host: str = "127.0.0.1",
    port: int = 8765,
    ssl_certfile: str | None = None,
    ssl_keyfile: str | None = None,
    max_ticks: int | None = None,
    auto_save: bool = True,
) -> WebTeleop:
    """Run the web app until Ctrl+C (or ``max_ticks``); returns the finished back end."""
    teleop = WebTeleop(env_id, seed=seed, save=save, hz=hz, auto_save=auto_save, frame_process=True)
    ssl = {}
    if ssl_certfile:
        ssl = {"ssl_certfile": ssl_certfile, "ssl_keyfile": ssl_keyfile}
    server = ServerThread(teleop.app, host=host, port=port, **ssl)
    bound = server.start()
    scheme = "https" if ssl_certfile else "http"
    shown = "localhost" if host in ("127.0.0.1", "0.0.0.0") else host
    if host == "0.0.0.0":
        import socket

        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.connect(("10.255.255.255", 1))
                shown = s.getsockname()[0]
            except OSError:
                shown = "localhost"
    print_url(f"{scheme}://{shown}:{bound}/?token={teleop.token}")
    previous = _stop_on_signals(teleop)
    try:
        teleop.run(max_ticks=max_ticks)
    except KeyboardInterrupt:
        pass
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        server.stop()
        teleop.close()
    return teleop


def _stop_on_signals(teleop: WebTeleop) -> dict[int, Any]:
    """Make Ctrl+C (SIGINT) and SIGTERM end the loop after its current tick, so an episode being
    saved is written whole and the caller's clean-up (closing the frame worker, building the
    dataset) runs; a second signal interrupts at once. Returns the handlers it replaced (none
    outside the main thread, where signals cannot be caught)."""
    if threading.current_thread() is not threading.main_thread():
        return {}

    def handler(signum: int, frame: Any) -> None:
        if teleop.loop.quit:
            raise KeyboardInterrupt
        print(f"\n{signal.Signals(signum).name}: stopping after this tick", flush=True)
        teleop.loop.quit = True

    return {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
