"""``kinder demo``: the showcase run (bilevel planning beside MPC and random, GIFs and a report)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

import kinder_core
from kinder_bench.cli.common import user_errors


def demo(
    out: Annotated[Path, typer.Option(help="Run directory.")] = Path("runs/demo"),
    workers: Annotated[int, typer.Option(help="Worker processes.")] = 2,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
) -> None:
    """The main job: bilevel planning next to MPC and random on four of the paper's envs (2D and
    3D, about two minutes on 2 cores); prints the table, writes GIFs and an HTML report."""
    from kinder_bench.demo import run_demo

    with user_errors():
        result = run_demo(out, workers=workers, progress=progress)
    typer.echo(result.table)
    videos = [p for p in result.files if p.suffix in (".gif", ".mp4")]
    others = [p for p in result.files if p not in videos]
    typer.echo(
        f"wrote {len(videos)} episode GIFs to {out / 'videos'}/ and "
        + ", ".join(p.name for p in others)
        + f" to {out}/"
    )
    n_envs = len(kinder_core.list_envs())
    typer.echo(
        f"demo finished in {result.seconds:.1f} s; {n_envs} environments are registered "
        f"(`kinder envs` lists them)."
    )
    typer.secho("Where to look:", bold=True)
    if result.html is not None:
        typer.echo(f"  {result.html.resolve()}  the report page: table, plot, GIFs, filters")
    typer.echo(f"  {out / 'paper_table.md'}  our figures beside the paper's Table II")
    typer.echo(f"  {out / 'videos'}/  one GIF per env, method and seed")
    typer.echo("  `kinder bench run --suite paper --agent all` runs the paper's protocol.")
