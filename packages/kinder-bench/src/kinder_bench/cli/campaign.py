"""``kinder bench campaign FILE.toml``: train and evaluate every cell of a campaign file,
resumably, over the runner's executors (see :mod:`kinder_bench.campaign`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from kinder_bench.cli.common import fail, user_errors
from kinder_bench.evaluation.executors import EXECUTORS


def campaign_cmd(
    config: Annotated[Path, typer.Argument(help="The campaign file (TOML).")],
    out: Annotated[
        Path | None, typer.Option(help="Output root (default: the file's [campaign] out).")
    ] = None,
    only: Annotated[
        list[str] | None,
        typer.Option(help="Run only this cell (its name, or NAME/ENV). Repeatable."),
    ] = None,
    executor: Annotated[str, typer.Option(help=f"One of {', '.join(EXECUTORS)}.")] = "process",
    workers: Annotated[
        int | None, typer.Option(help="Worker processes / local Ray CPUs (default: all CPUs).")
    ] = None,
    address: Annotated[
        str | None, typer.Option(help="Ray cluster address (with --executor ray).")
    ] = None,
    dry_run: Annotated[
        bool, typer.Option(help="List the cells, their training commands and run settings only.")
    ] = False,
    report: Annotated[
        bool, typer.Option(help="Write the paper comparison over OUT/eval at the end.")
    ] = True,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
) -> None:
    """Train where needed, evaluate every cell through the runner into OUT/eval, and record each
    cell's status in OUT/campaign.json. Rerunning the same command resumes: finished trainings
    and episodes are skipped."""
    from kinder_bench.campaign import load_campaign, run_campaign, train_command

    if executor not in EXECUTORS:
        fail(f"--executor {executor!r}: expected one of {list(EXECUTORS)}")
    with user_errors():
        campaign = load_campaign(config)
    root = out or campaign.out
    if dry_run:
        for cell in campaign.cells:
            if only and cell.name not in only and cell.key not in only:
                continue
            run = cell.run_config(root)
            typer.echo(
                f"{cell.key}: {cell.agent} {dict(run.agent_args)} seeds {list(cell.seeds)} × "
                f"{cell.episodes}, max_steps {cell.max_steps or 'paper/env default'}"
                + (f", label {cell.label}" if cell.label else "")
                + (f", obs noise {cell.obs_noise:g}" if cell.obs_noise else "")
                + (f", action noise {cell.action_noise:g}" if cell.action_noise else "")
            )
            if cell.train is not None:
                seeds = cell.seeds if cell.train.per_seed else (None,)
                for seed in seeds:
                    typer.echo("    " + " ".join(train_command(cell, root, seed)))
        return
    with user_errors():
        outcome = run_campaign(campaign, root, executor=executor, workers=workers,
                               address=address, only=tuple(only or ()), progress=progress,
                               log=lambda m: typer.echo(m, err=True))  # fmt: skip
    finished = sum(bool(s.get("finished")) for s in outcome.status)
    typer.echo(
        f"{root}: {len(outcome.status)} cells ({finished} finished), trained "
        f"{outcome.trained} models, ran {outcome.episodes_ran} episodes, skipped "
        f"{outcome.episodes_skipped} already done; status in {root / 'campaign.json'}",
        err=True,
    )
    if report and outcome.episodes_ran + outcome.episodes_skipped:
        from kinder_bench.reporting.report import write_report

        with user_errors():
            md, _ = write_report([root / "eval"], plot=False, paper=True)
        typer.echo(md)
    if outcome.failed:
        fail(f"training failed for {outcome.failed} (see above); the other cells ran")
