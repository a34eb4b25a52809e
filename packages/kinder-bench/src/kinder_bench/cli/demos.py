"""``kinder demos``: collect, build, replay, inspect and convert demonstration datasets.

* ``collect``: run an agent (the bilevel planner by default: skill-labelled; ``mpc``; any
  scripted ``module:Class`` agent) until N successful episodes are kept, in parallel through the
  runner's executors, resumably; then build the LeRobot dataset (images rendered by replay).
* ``build``: (re)build the LeRobot dataset of a collection directory.
* ``replay``: replay every episode from its seed; states must match to 1e-9.
* ``info`` / ``show``: counts, lengths, success, skills, size, checksum; a GIF of an episode.
* ``convert``: upstream pickles / HDF5 / LeRobot datasets into LeRobot datasets or HDF5.
* ``export-openpi``: a dataset in the LeRobot v2.1 layout openpi reads (π0.5 fine-tuning).
* ``datasets``: the project's ten datasets (``make datasets``): collect, build, write the cards.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Annotated, Any

import typer

from kinder_bench.cli.common import fail, load_imports, parse_agent_args, user_errors

demos_app = typer.Typer(
    help="Demonstrations: collect, build, replay, inspect and convert datasets.",
    no_args_is_help=True,
)

# The options of `kinder bench run`, with this group's help texts.
ImportOpt = Annotated[
    list[str] | None,
    typer.Option("--import", help="Module to import first (and in every worker). Repeatable."),
]
ArgOpt = Annotated[
    list[str] | None,
    typer.Option("--arg", help="Agent argument KEY=VALUE (see `kinder agents`). Repeatable."),
]
ImagesOpt = Annotated[bool, typer.Option(help="Render camera images into the dataset (videos).")]


def _dataset_errors() -> Any:
    from kinder_gym.demos.lerobot_format import DatasetError
    from kinder_gym.demos.store import EpisodeFileError
    from kinder_gym.demos.upstream import UpstreamFormatError

    return (DatasetError, EpisodeFileError, UpstreamFormatError)


@demos_app.command("collect")
def collect_cmd(
    env_id: Annotated[str, typer.Argument(help="Environment id, e.g. Motion2D-p0.")],
    out: Annotated[Path, typer.Option(help="Collection directory (resumable).")],
    agent: Annotated[str, typer.Option(help="Agent producing the demos.")] = "bilevel_planning",
    args: ArgOpt = None,
    episodes: Annotated[int, typer.Option(help="Successful episodes to keep.")] = 100,
    seed: Annotated[
        int, typer.Option(help="Collection seed (1000: instances apart from evaluation's 0-4).")
    ] = 1000,
    max_steps: Annotated[int | None, typer.Option(help="Step budget per attempt.")] = None,
    max_attempts: Annotated[
        int | None, typer.Option(help="Attempt budget (default 10 × episodes).")
    ] = None,
    executor: Annotated[str, typer.Option(help="process, inline or ray.")] = "process",
    workers: Annotated[int | None, typer.Option(help="Worker processes.")] = None,
    dataset: Annotated[
        Path | None, typer.Option(help="LeRobot dataset to build (default: OUT/lerobot).")
    ] = None,
    build: Annotated[bool, typer.Option(help="Build the LeRobot dataset afterwards.")] = True,
    images: ImagesOpt = True,
    progress: Annotated[bool, typer.Option(help="Show progress bars.")] = True,
    imports: ImportOpt = None,
) -> None:
    """Collect successful demonstrations of one env (resumable), then build the dataset."""
    from kinder_bench.demos.collection import (
        CollectConfig,
        build_dataset,
        collect,
        evaluation_overlap,
        resolve_collect,
    )

    mods = load_imports(imports)
    agent_args = parse_agent_args(args, [agent])[agent]
    config = CollectConfig(env_id, agent, agent_args, episodes, seed, max_steps, max_attempts)
    with user_errors():
        shared = evaluation_overlap(seed, resolve_collect(config).max_attempts)
        if shared:
            typer.secho(
                f"warning: collection seed {seed} draws {len(shared)} instances that evaluation "
                "seeds 0-4 also use; policies trained on them are evaluated on seen instances",
                fg=typer.colors.YELLOW,
                err=True,
            )
        outcome = collect(config, out, executor, workers, mods, progress)
    n, tried = len(outcome.kept), outcome.attempted_for_kept
    typer.echo(
        f"{outcome.config.env_id}: kept {n}/{tried} attempts ({n / max(tried, 1):.0%}); "
        f"{outcome.ran} attempts run now in {outcome.seconds:.1f} s"
    )
    if not outcome.complete:
        typer.secho(
            f"only {n} of {episodes} episodes: the attempt budget "
            f"({outcome.config.max_attempts}) is spent",
            fg=typer.colors.YELLOW,
            err=True,
        )
    if build and n:
        target = dataset or out / "lerobot"
        with user_errors():
            build_dataset(out, target, images=images, progress=progress)
        typer.echo(f"wrote {target}")


@demos_app.command("build")
def build_cmd(
    collection: Annotated[Path, typer.Argument(help="A collection directory.")],
    dataset: Annotated[Path, typer.Argument(help="The LeRobot dataset directory.")],
    images: ImagesOpt = True,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
) -> None:
    """Build (or finish building) the LeRobot dataset of a collection."""
    from kinder_bench.demos.collection import build_dataset

    with user_errors():
        n = build_dataset(collection, dataset, images=images, progress=progress)
    typer.echo(f"wrote {dataset} ({n} episodes)")


@demos_app.command("replay")
def replay_cmd(
    dataset: Annotated[Path, typer.Argument(help="A LeRobot demo dataset.")],
    atol: Annotated[float, typer.Option(help="Tolerance on every state feature.")] = 1e-9,
) -> None:
    """Replay every episode from its seed; report the ones that do not reproduce (exit 1)."""
    import kinder_core
    from kinder_gym.demos.lerobot_format import load_records, read_kinder_meta
    from kinder_gym.demos.replay import replay_record

    try:
        meta = read_kinder_meta(dataset)
        records = load_records(dataset)
    except _dataset_errors() as e:
        fail(str(e))
    env = kinder_core.make(meta["env_id"])
    bad = []
    for i, record in enumerate(records):
        result = replay_record(env, record, atol, name=f"episode {i} (seed {record.seed})")
        if not result.ok:
            bad.append(result.message)
    typer.echo(
        f"{dataset}: {len(records) - len(bad)}/{len(records)} episodes replay within {atol:g}"
    )
    if bad:
        for message in bad:
            typer.secho(message, fg=typer.colors.RED, err=True)
        raise typer.Exit(1)


@demos_app.command("info")
def info_cmd(
    dataset: Annotated[Path, typer.Argument(help="A LeRobot demo dataset.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
) -> None:
    """Counts, lengths, success, skills, size on disk and the content checksum."""
    from kinder_gym.demos.summary import dataset_summary

    try:
        summary = dataset_summary(dataset)
    except _dataset_errors() as e:
        fail(str(e))
    if as_json:
        typer.echo(json.dumps(summary, indent=2, sort_keys=True))
        return
    s = summary
    typer.echo(
        f"{dataset}: {s['env_id']}\n"
        f"  episodes {s['episodes']} ({s['successes']} successful), frames {s['frames']}, "
        f"length mean {s['length_mean']:.1f} (min {s['length_min']}, max {s['length_max']})\n"
        f"  sources {s['sources']}, skill-labelled {s['skill_labelled']}, skills {s['skills']}\n"
        f"  cameras {s['cameras']} ({s['image_size']} px), fps {s['fps']}, state dim "
        f"{s['state_dim']} (robot: {s['robot_objects']}), action dim {s['action_dim']}\n"
        f"  size {s['size_bytes'] / 1e6:.2f} MB, checksum {s['checksum']}"
    )


@demos_app.command("show")
def show_cmd(
    dataset: Annotated[Path, typer.Argument(help="A LeRobot demo dataset.")],
    episode: Annotated[int, typer.Option(help="Episode index.")] = 0,
    out: Annotated[Path, typer.Option(help="GIF (or .mp4) to write.")] = Path("episode.gif"),
    camera: Annotated[
        str | None, typer.Option(help="Camera (default: the first; 3D: all side by side).")
    ] = None,
) -> None:
    """Write a GIF of one episode, rendered from its recorded states (as the dataset's images
    were), with the skill labels printed."""
    import numpy as np

    import kinder_core
    from kinder_bench.evaluation.recording import write_video
    from kinder_gym.demos.layout import (
        camera_frames,
        camera_names,
        image_env_kwargs,
        set_render_size,
    )
    from kinder_gym.demos.lerobot_format import load_records, read_kinder_meta

    try:
        meta = read_kinder_meta(dataset)
        (record,) = load_records(dataset, episodes=[episode])
    except (*_dataset_errors(), IndexError) as e:
        fail(str(e))
    size = int(meta["image_size"])
    env = kinder_core.make(meta["env_id"], **image_env_kwargs(meta["env_id"], size))
    set_render_size(env, size)
    names = camera_names(env)
    if camera is not None and camera not in names:
        fail(f"--camera {camera!r}: this env's cameras are {list(names)}")
    states = record.states if record.states is not None else record.observations
    frames = []
    for state in states:
        views = camera_frames(env, state, size)
        frames.append(views[camera] if camera else np.concatenate(list(views.values()), axis=1))
    write_video(out, frames, fps=int(meta["fps"]))
    for label in record.skills:
        typer.echo(f"  steps {label.start}-{label.end}: {label.operator}{label.objects}")
    typer.echo(f"wrote {out} ({len(frames)} frames, seed {record.seed})")


@demos_app.command("convert")
def convert_cmd(
    src: Annotated[
        Path,
        typer.Argument(
            help="Upstream pickle(s) (.p/.pkl file or directory), upstream HDF5 (.hdf5/.h5), "
            "a directory of episode files (.npz) or a LeRobot demo dataset."
        ),
    ],
    dst: Annotated[Path, typer.Argument(help="A LeRobot dataset directory, or a .hdf5 file.")],
    env: Annotated[
        str | None, typer.Option(help="Env id (needed for HDF5 input; else read from SRC).")
    ] = None,
    images: ImagesOpt = True,
) -> None:
    """Convert between demonstration formats."""
    import kinder_core
    from kinder_bench.evaluation.envs import resolve_env_id
    from kinder_gym.demos.layout import StateSplit
    from kinder_gym.demos.lerobot_format import DemoWriter, load_records
    from kinder_gym.demos.store import load_record
    from kinder_gym.demos.upstream import (
        find_upstream_pickles,
        load_upstream_hdf5,
        load_upstream_pickle,
        write_upstream_hdf5,
    )

    try:
        if src.suffix in (".hdf5", ".h5"):
            if env is None:
                fail("--env is required for HDF5 input (the file does not name its env)")
            records = load_upstream_hdf5(src, resolve_env_id(env))
        elif (src / "meta" / "info.json").exists():
            records = load_records(src)
        elif src.is_dir() and any(src.rglob("*.npz")):
            records = [load_record(p) for p in sorted(src.rglob("*.npz"))]
        else:
            paths = find_upstream_pickles(src)
            if not paths:
                fail(f"{src}: no demonstrations found (pickles, .npz, HDF5 or a LeRobot dataset)")
            records = [load_upstream_pickle(p) for p in paths]
        if not records:
            fail(f"{src}: no episodes")
        env_id = resolve_env_id(env or records[0].env_id)
        records = [r for r in records if r.env_id == env_id or env is not None]
        if dst.suffix in (".hdf5", ".h5"):
            split = StateSplit.from_env(kinder_core.make(env_id))
            write_upstream_hdf5(dst, records, split)
        else:
            with DemoWriter(dst, env_id, images=images) as writer:
                for record in records:
                    if record.env_id != env_id:
                        record = type(record)(**{**record.__dict__, "env_id": env_id})
                    writer.add(record)
    except (*_dataset_errors(), ValueError) as e:
        fail(str(e))
    typer.echo(f"wrote {dst} ({len(records)} episodes of {env_id})")


@demos_app.command("datasets")
def datasets_cmd(
    names: Annotated[
        list[str] | None, typer.Argument(help="Dataset names (default: all ten).")
    ] = None,
    base: Annotated[Path, typer.Option(help="The datasets directory.")] = Path("datasets"),
    collect_: Annotated[bool, typer.Option("--collect/--no-collect", help="Collect.")] = True,
    build: Annotated[bool, typer.Option(help="Build the LeRobot datasets.")] = True,
    card: Annotated[bool, typer.Option(help="Write the dataset cards.")] = True,
    executor: Annotated[str, typer.Option(help="process, inline or ray.")] = "process",
    workers: Annotated[int | None, typer.Option(help="Worker processes.")] = None,
    progress: Annotated[bool, typer.Option(help="Show progress bars.")] = True,
) -> None:
    """The project's datasets (``make datasets``): collect, build and describe each one."""
    from kinder_bench.demos.cards import write_card
    from kinder_bench.demos.collection import build_dataset, collect
    from kinder_bench.demos.specs import DATASETS, dataset_spec

    with user_errors():
        specs = [dataset_spec(n) for n in names] if names else list(DATASETS.values())
    for spec in specs:
        started = time.perf_counter()
        with user_errors():
            if collect_:
                outcome = collect(
                    spec.collect_config(),
                    spec.collection_dir(base),
                    executor,
                    workers,
                    progress=progress,
                )
                typer.echo(
                    f"{spec.name}: kept {len(outcome.kept)}/{outcome.attempted_for_kept} "
                    f"attempts ({outcome.seconds:.1f} s)"
                )
            if build and spec.collection_dir(base).exists():
                build_dataset(
                    spec.collection_dir(base),
                    spec.dataset_dir(base),
                    images=spec.images,
                    progress=progress,
                )
            if card:
                path = write_card(spec, base)
                typer.echo(f"{spec.name}: wrote {path}")
        typer.echo(f"{spec.name}: {time.perf_counter() - started:.1f} s")


@demos_app.command("export-openpi")
def export_openpi_cmd(
    dataset: Annotated[Path, typer.Argument(help="A KinDER LeRobot demo dataset (v3).")],
    out: Annotated[
        Path,
        typer.Argument(
            help="The export directory; openpi finds it as $HF_LEROBOT_HOME/<repo_id>, so "
            "name it e.g. $HF_LEROBOT_HOME/kinder/Motion2D-p0."
        ),
    ],
    images: Annotated[
        bool, typer.Option(help="Render the camera images (PNG in the parquet files).")
    ] = True,
    overwrite: Annotated[bool, typer.Option(help="Replace a non-empty OUT.")] = False,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
) -> None:
    """Export a dataset to the LeRobot v2.1 layout openpi's data loader reads (π0.5
    fine-tuning; see docs/vla.md)."""
    from tqdm import tqdm

    from kinder_gym.demos.openpi_format import ExportError, export_openpi

    bar = tqdm(disable=not progress, desc="export-openpi", unit="episode")

    def step(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    try:
        summary = export_openpi(dataset, out, images=images, overwrite=overwrite, progress=step)
    except (*_dataset_errors(), ExportError, FileNotFoundError) as e:
        fail(str(e))
    finally:
        bar.close()
    typer.echo(
        f"wrote {summary.out}: {summary.episodes} episodes, {summary.frames} frames of "
        f"{summary.env_id} (images {list(summary.image_keys)}, state {summary.state_dim}, "
        f"environment_state {summary.env_state_dim}, actions {summary.action_dim}, "
        f"fps {summary.fps})"
    )
