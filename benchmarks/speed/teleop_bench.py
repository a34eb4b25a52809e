"""Teleoperation figures: message→action latency and sustained control rate of the 3D web app
(touch pads and the phone's AR pose path), and frames per second of the 2D pygame window.

Usage:
    python benchmarks/speed/teleop_bench.py web [--env kinder/BaseMotion3D-v0] [--hz 10] \
        [--seconds 20]
        [--frame-every 3]
    python benchmarks/speed/teleop_bench.py phone [--env kinder/Shelf3D-o1-v0] [--hz 10] \
        [--seconds 20]
    python benchmarks/speed/teleop_bench.py window [--env kinder/Motion2D-p0-v0] [--ticks 400]
    python benchmarks/speed/teleop_bench.py table RESULTS.jsonl  # README tables of saved records

``web`` starts the real server (uvicorn on 127.0.0.1) and the teleop loop in this process and a
WebSocket client thread that streams input messages at 60 Hz (base and arm clutches engaged, both
devices moving, so the IK runs every tick). Per run it reports the latency from a message's
arrival at the server to the env action it produced being applied (the loop's ``latencies``:
receive time → after ``env.step``; only the newest message at a tick is used), the achieved
control rate at the requested ``hz``, and the largest sustainable rate (the same loop
unthrottled: ``hz`` = 1000, every tick back to back, frames and status included), each with the
camera frames rendered in a separate process (what ``kinder teleop --web`` does) and in the loop
thread every ``--frame-every`` ticks.

``phone`` compares the two phone paths driving the arm (the IK runs every tick) with camera
frames in a separate process, as ``kinder teleop --web`` runs: an emulated phone in AR (a
client sending the page's ``phone-ar`` messages, the raw viewer pose of a phone moving on a
5 cm circle and turning ±0.3 rad, at the display rate of 60 Hz, finger on the arm zone) beside
the touch pads' messages (the arm pad dragged on the same circle, at the page's 30 Hz). Same
measures as ``web``, plus the share of ticks that stepped the env (control held), and first the
server's cost per message of each path (``WebHub.handle_text`` and ``poll``, no network).

``window`` runs the 2D window with SDL's dummy video driver (software only, no display: a
lower bound for a real window, which adds the compositor) unthrottled with a key held, and
reports frames per second (render, scale, draw, flip) and at the default 20 Hz the achieved rate.

Prints one JSON object per measurement.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import threading
import time
from typing import Any


def _message(device: str, seq: int, t: float) -> dict[str, Any]:
    """The input message ``device`` sends at time ``t`` (s) of the run."""
    msg: dict[str, Any] = {"v": 2, "type": "input", "seq": seq, "sent": time.time() * 1000.0}
    if device == "script":  # base and arm both moving
        z = -0.3 * (1.0 - abs((t % 4.0) - 2.0) / 2.0)  # back and forth, 0 … −0.3 m
        a = 0.05 * math.sin(2.0 * t)
        msg |= {
            "device": "script",
            "engaged": ["base", "arm"],
            "poses": {
                "base": {"grab": 1, "p": [0.0, 0.0, z], "q": [0, 0, 0, 1]},
                "arm": {"grab": 1, "p": [a, a, 0.0], "q": [0, 0, 0, 1]},
            },
        }
        return msg
    # The phone (or the finger on the arm pad) on a 5 cm circle; the AR phone also turns.
    circle = [0.05 * math.cos(t), 0.05 * math.sin(t), -0.05 * math.sin(t)]
    if device == "touch":
        msg |= {
            "device": "phone",
            "engaged": ["arm"],
            "poses": {"arm": {"grab": 1, "p": circle, "q": [0, 0, 0, 1]}},
            "gripper": 0.0,
        }
        return msg
    yaw = 0.3 * math.sin(0.5 * t)
    msg |= {
        "device": "phone-ar",
        "engaged": ["arm"],
        "viewer": {
            "p": [circle[0], 1.4 + circle[1], circle[2]],
            "q": [0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2)],
        },
        "gripper": 0.0,
    }
    return msg


def _client(url: str, stop: threading.Event, rate_hz: float, device: str = "script") -> None:
    from websockets.sync.client import connect

    with connect(url) as ws:
        seq = 0
        t0 = time.perf_counter()

        def drain() -> None:
            try:
                while not stop.is_set():
                    ws.recv(timeout=0.5)
            except Exception:
                return

        reader = threading.Thread(target=drain, daemon=True)
        reader.start()
        while not stop.is_set():
            ws.send(json.dumps(_message(device, seq, time.perf_counter() - t0)))
            seq += 1
            time.sleep(1.0 / rate_hz)


def bench_web(
    env_id: str,
    hz: float,
    seconds: float,
    frame_every: int,
    frame_process: bool,
    device: str = "script",
    rate_hz: float = 60.0,
) -> dict[str, Any]:
    from kinder_gym.teleop.loop import latency_summary
    from kinder_gym.teleop.web.server import ServerThread, WebTeleop

    teleop = WebTeleop(
        env_id, hz=hz, frame_every=frame_every, auto_save=False, frame_process=frame_process
    )
    server = ServerThread(teleop.app)
    port = server.start()
    stop = threading.Event()
    url = f"ws://127.0.0.1:{port}/ws?token={teleop.token}"
    client = threading.Thread(target=_client, args=(url, stop, rate_hz, device), daemon=True)
    client.start()
    time.sleep(0.5)
    teleop.loop.latencies.clear()
    ticks0, steps0 = teleop.loop.ticks, teleop.loop.total_steps
    tick_times: list[float] = []

    def timed_after() -> None:
        teleop.after_tick()
        tick_times.append(time.perf_counter())

    start = time.perf_counter()
    period = 1.0 / hz
    next_t = start
    while time.perf_counter() - start < seconds:
        teleop.loop.tick()
        timed_after()
        next_t += period
        now = time.perf_counter()
        if next_t < now - period:
            next_t = now
        elif next_t > now:
            time.sleep(next_t - now)
    elapsed = time.perf_counter() - start
    stop.set()
    client.join(timeout=5)
    server.stop()
    frames = teleop.hub.frames_set
    teleop.close()
    ticks = teleop.loop.ticks - ticks0
    return {
        "measure": "web",
        "env_id": env_id,
        "device": device,
        "message_hz": rate_hz,
        "hz_requested": hz,
        "frames": "process" if frame_process else f"loop thread every {frame_every} ticks",
        "frame_updates_per_s": round(frames / elapsed, 2),
        "seconds": round(elapsed, 2),
        "ticks": ticks,
        "control_hz": round(ticks / elapsed, 2),
        "env_steps": teleop.loop.total_steps - steps0,
        "held": round((teleop.loop.total_steps - steps0) / max(ticks, 1), 3),
        "messages_received": teleop.hub.received,
        "latency": {k: round(v, 2) for k, v in latency_summary(teleop.loop.latencies).items()},
    }


def bench_hub(device: str, n: int = 20_000) -> dict[str, Any]:
    """Server cost of one input message: ``WebHub.handle_text`` (parse, checks, the viewer
    pose's clutch for AR) and one ``poll``, in microseconds per message."""
    from kinder_gym.teleop.web.hub import WebHub

    hub = WebHub(max_age=1e9)
    cid = hub.connect()
    texts = [json.dumps(_message(device, seq, seq / 60.0)) for seq in range(n)]
    start = time.perf_counter()
    for text in texts:
        hub.handle_text(cid, text)
        hub.poll(0.0)
    elapsed = time.perf_counter() - start
    return {
        "measure": "hub",
        "device": device,
        "messages": n,
        "bytes_per_message": round(sum(len(t) for t in texts) / n, 1),
        "us_per_message": round(elapsed / n * 1e6, 2),
    }


def bench_window(env_id: str, ticks: int) -> list[dict[str, Any]]:
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    import pygame

    from kinder_gym.teleop.gui2d import Teleop2DApp

    out = []
    for hz in (1000.0, 20.0):
        app = Teleop2DApp(env_id, hz=hz, open_controllers=False, auto_save=False)
        pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_q, mod=0))
        n = ticks if hz > 100 else min(ticks, 100)
        start = time.perf_counter()
        app.run(max_ticks=n)
        elapsed = time.perf_counter() - start
        out.append(
            {
                "measure": "window",
                "env_id": env_id,
                "hz_requested": hz,
                "frames": app.frames,
                "seconds": round(elapsed, 2),
                "fps": round(app.frames / elapsed, 1),
                "window": list(app.screen.get_size()),
            }
        )
        app.close()
    return out


def table(path: str) -> str:
    """Markdown tables of the records in ``path`` (one JSON object per line)."""
    with open(path) as f:
        rows = [json.loads(line) for line in f if line.strip()]
    web = [r for r in rows if r["measure"] == "web" and r.get("device", "script") == "script"]
    out = []
    if web:
        out += [
            "| env | frames rendered | requested Hz | control Hz | latency mean / p50 / p95 / "
            "max ms | frame updates/s |",
            "|---|---|---|---|---|---|",
        ]
    for r in web:
        lat = r["latency"]
        req = "unthrottled" if r["hz_requested"] > 100 else f"{r['hz_requested']:g}"
        where = "separate process" if r["frames"] == "process" else "loop thread, every 3 ticks"
        out.append(
            f"| {r['env_id']} | {where} | {req} | {r['control_hz']} | {lat['mean_ms']} / "
            f"{lat['p50_ms']} / {lat['p95_ms']} / {lat['max_ms']} | {r['frame_updates_per_s']} |"
        )
    phone = [r for r in rows if r["measure"] == "web" and r.get("device") in ("touch", "phone-ar")]
    if phone:
        out += [
            "",
            "| env | path | messages/s | requested Hz | control Hz | ticks stepped "
            "| latency mean / p50 / p95 / max ms |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in phone:
            lat = r["latency"]
            path = "phone AR (viewer pose)" if r["device"] == "phone-ar" else "touch pads"
            req = "unthrottled" if r["hz_requested"] > 100 else f"{r['hz_requested']:g}"
            out.append(
                f"| {r['env_id']} | {path} | {r['message_hz']:g} | {req} | {r['control_hz']} "
                f"| {r['held']:.0%} | {lat['mean_ms']} / {lat['p50_ms']} / {lat['p95_ms']} / "
                f"{lat['max_ms']} |"
            )
    hub = [r for r in rows if r["measure"] == "hub"]
    if hub:
        out += ["", "| path | bytes per message | server µs per message |", "|---|---|---|"]
    for r in hub:
        path = "phone AR (viewer pose)" if r["device"] == "phone-ar" else "touch pads"
        out.append(f"| {path} | {r['bytes_per_message']} | {r['us_per_message']} |")
    windows = [r for r in rows if r["measure"] == "window"]
    if windows:
        out += ["", "| env | window | requested Hz | frames per second |", "|---|---|---|---|"]
    for r in windows:
        if r["measure"] == "window":
            req = "unthrottled" if r["hz_requested"] > 100 else f"{r['hz_requested']:g}"
            size = "×".join(str(v) for v in r["window"])
            out.append(f"| {r['env_id']} | {size} | {req} | {r['fps']} |")
    return "\n".join(out).strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    web = sub.add_parser("web")
    web.add_argument("--env", default="kinder/BaseMotion3D-v0")
    web.add_argument("--hz", type=float, default=10.0)
    web.add_argument("--seconds", type=float, default=20.0)
    web.add_argument("--frame-every", type=int, default=3)
    phone = sub.add_parser("phone")
    phone.add_argument("--env", default="kinder/Shelf3D-o1-v0")
    phone.add_argument("--hz", type=float, default=10.0)
    phone.add_argument("--seconds", type=float, default=20.0)
    window = sub.add_parser("window")
    window.add_argument("--env", default="kinder/Motion2D-p0-v0")
    window.add_argument("--ticks", type=int, default=400)
    tab = sub.add_parser("table")
    tab.add_argument("path")
    args = parser.parse_args()
    if args.what == "table":
        print(table(args.path))
    elif args.what == "web":
        for frame_process in (True, False):
            for hz in (args.hz, 1000.0):
                record = bench_web(args.env, hz, args.seconds, args.frame_every, frame_process)
                print(json.dumps(record), flush=True)
    elif args.what == "phone":
        for device in ("phone-ar", "touch"):
            print(json.dumps(bench_hub(device)), flush=True)
        for hz in (args.hz, 1000.0):
            for device, rate in (("phone-ar", 60.0), ("touch", 30.0)):
                record = bench_web(args.env, hz, args.seconds, 0, True, device, rate)
                print(json.dumps(record), flush=True)
    else:
        for record in bench_window(args.env, args.ticks):
            print(json.dumps(record), flush=True)


if __name__ == "__main__":
    main()
