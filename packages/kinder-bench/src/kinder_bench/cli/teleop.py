"""``kinder teleop``: collect demonstrations by hand (kinder-gym's teleoperation, ``[teleop]``).

2D ids open a pygame window (keyboard, mouse sticks, any SDL game controller); 3D ids open the
same window with keyboard/gamepad bindings, or with ``--web`` serve the phone / WebXR page (URL and
QR code in the terminal). Saved episodes go to ``--out`` at once, one atomic file each
(``OUT/episodes/``); on exit they are appended to the LeRobot dataset ``OUT/lerobot``
(``kinder demos replay OUT/lerobot`` checks them). See ``kinder_gym.teleop``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from kinder_bench.cli.common import fail, user_errors


def teleop_cmd(
    env_id: Annotated[
        str, typer.Argument(help="Environment id, e.g. Motion2D-p0 or BaseMotion3D.")
    ],
    out: Annotated[
        Path | None, typer.Option(help="Output directory (default: demos/teleop/<id>).")
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the first episode (then +1 each).")] = 0,
    web: Annotated[bool, typer.Option("--web", help="3D: serve the phone / WebXR page.")] = False,
    hz: Annotated[
        float | None, typer.Option(help="Control rate (default 20 Hz in 2D, 10 Hz in 3D).")
    ] = None,
    host: Annotated[
        str, typer.Option(help="--web: bind address (0.0.0.0 to reach it from a phone).")
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="--web: port.")] = 8765,
    ssl_certfile: Annotated[
        str | None, typer.Option(help="--web: TLS certificate (WebXR on a LAN device needs HTTPS).")
    ] = None,
    ssl_keyfile: Annotated[str | None, typer.Option(help="--web: TLS key.")] = None,
    auto_save: Annotated[bool, typer.Option(help="Save successful episodes automatically.")] = True,
    images: Annotated[bool, typer.Option(help="Render camera videos into the dataset.")] = True,
    build: Annotated[bool, typer.Option(help="Append new episodes to OUT/lerobot on exit.")] = True,
    build_only: Annotated[
        bool, typer.Option("--build-only", help="Only append saved episodes to the dataset.")
    ] = False,
) -> None:
    """Teleoperate an environment and record demonstrations."""
    from kinder_bench.evaluation.envs import resolve_env_id, short_id

    with user_errors():
        full = resolve_env_id(env_id)
    try:
        from kinder_gym.teleop.app import is_2d, run_window
        from kinder_gym.teleop.saving import TeleopSaver
    except ModuleNotFoundError as e:
        fail(f"{e}; install the teleop extra: pip install 'kinder-gym[teleop]'")
    target = out or Path("demos") / "teleop" / short_id(full)
    saver = TeleopSaver(target, full)
    if not build_only:
        with user_errors():
            if web:
                if is_2d(full):
                    fail(f"{full} is a 2D env: --web serves the 3D robot; drop --web")
                from kinder_gym.teleop.web.server import serve

                serve(
                    full,
                    seed=seed,
                    save=saver,
                    hz=hz or 10.0,
                    host=host,
                    port=port,
                    ssl_certfile=ssl_certfile,
                    ssl_keyfile=ssl_keyfile,
                    auto_save=auto_save,
                )
            else:
                run_window(full, seed=seed, save=saver, hz=hz, auto_save=auto_save)
        typer.echo(f"{len(saver.files())} episode files in {saver.episodes_dir}")
    if build or build_only:
        with user_errors():
            added = saver.build(images=images)
        typer.echo(f"added {added} episodes to {saver.dataset_dir}")
