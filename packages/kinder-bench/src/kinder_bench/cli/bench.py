"""``kinder bench``: run agents on envs over seeds (resumably) and report the results."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from kinder_bench.agents import AGENTS, agent_class
from kinder_bench.cli.common import (
    ArgOpt,
    ImportOpt,
    fail,
    load_imports,
    parse_agent_args,
    parse_seeds,
    user_errors,
)
from kinder_bench.evaluation.envs import short_id
from kinder_bench.evaluation.executors import EXECUTORS
from kinder_bench.evaluation.recording import VIDEO_FORMATS

bench_app = typer.Typer(help="Run benchmarks and report their results.", no_args_is_help=True)


@bench_app.command("run")
def bench_run(
    env: Annotated[
        list[str] | None, typer.Option("--env", "-e", help="Environment id. Repeatable.")
    ] = None,
    suite: Annotated[
        str | None,
        typer.Option(help="'paper': the paper's eight benchmark envs (those installed)."),
    ] = None,
    agent: Annotated[
        list[str] | None,
        typer.Option(
            "--agent",
            "-a",
            help="Agent name, or 'all': every registered agent that can run here (the others "
            "are listed with the reason). Repeatable.",
        ),
    ] = None,
    args: ArgOpt = None,
    seeds: Annotated[str, typer.Option(help="Run seeds: '0-4' or '0,1,2'.")] = "0-4",
    episodes: Annotated[int, typer.Option(help="Episodes per seed.")] = 50,
    max_steps: Annotated[
        int | None,
        typer.Option(
            help="Step budget per episode (default: the paper's for its envs, else the env's)."
        ),
    ] = None,
    out: Annotated[Path, typer.Option(help="Run directory (reruns resume it).")] = Path(
        "runs/bench"
    ),
    executor: Annotated[str, typer.Option(help=f"One of {', '.join(EXECUTORS)}.")] = "process",
    workers: Annotated[
        int | None, typer.Option(help="Worker processes / local Ray CPUs (default: all CPUs).")
    ] = None,
    address: Annotated[
        str | None, typer.Option(help="Ray cluster address (with --executor ray).")
    ] = None,
    record: Annotated[
        str | None, typer.Option(help=f"Record episodes as {' or '.join(VIDEO_FORMATS)}.")
    ] = None,
    record_episodes: Annotated[
        int, typer.Option(help="Record the first N episodes of each seed (-1: all).")
    ] = 1,
    record_frames: Annotated[
        int | None,
        typer.Option(
            help="Record about N frames per episode at most: every ceil(max_steps/N)-th step "
            "(default: every step)."
        ),
    ] = None,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
    report: Annotated[bool, typer.Option(help="Write and print the report at the end.")] = True,
    html: Annotated[bool, typer.Option(help="The report also writes report.html.")] = False,
    label: Annotated[
        str | None,
        typer.Option(
            help="The method's name in the tables (default: the agent's; one agent only). A "
            "name other than the agent's marks a variant (e.g. ppo-dense): it gets its own "
            "row, never the paper's column."
        ),
    ] = None,
    training: Annotated[
        str,
        typer.Option(
            help="The training budget of the agent's checkpoints, in words (e.g. '1M env "
            "steps'), recorded in the summary rows: a learned agent fills a paper cell only "
            "with the paper's (kinder_bench/data/paper_settings.csv)."
        ),
    ] = "",
    obs_noise: Annotated[
        float,
        typer.Option(
            help="Std of Gaussian noise on every observation entry (clipped to the bounds), as "
            "in the paper's noise table; a run under noise is a variant, never a paper cell."
        ),
    ] = 0.0,
    action_noise: Annotated[
        float,
        typer.Option(help="Std of Gaussian noise on every action entry (clipped to the bounds)."),
    ] = 0.0,
    imports: ImportOpt = None,
) -> None:
    """Run every agent on every env over the seeds (resuming what the run directory has).

    With ``--suite paper`` the report at the end is the paper comparison (Table II's layout)."""
    from kinder_bench.evaluation.runner import RunConfig, run_benchmark

    mods = load_imports(imports)
    envs_ = list(env or []) + _suite_envs(suite)
    if not envs_:
        fail("give at least one --env (or --suite paper)")
    if executor not in EXECUTORS:
        fail(f"--executor {executor!r}: expected one of {list(EXECUTORS)}")
    if label is not None and (len(agent or []) != 1 or agent == ["all"] or not label.strip()):
        fail(f"--label {label!r}: expected a non-empty name and exactly one --agent")
    pairs = _runnable(envs_, agent or ["random"], args)
    seed_list = parse_seeds(seeds)
    runs = [
        RunConfig(
            e,
            a,
            a_args,
            seed_list,
            episodes,
            max_steps,
            label=label,
            training=training,
            obs_noise=obs_noise,
            action_noise=action_noise,
        )
        for e, a, a_args in pairs
    ]
    with user_errors():
        outcome = run_benchmark(
            runs,
            out,
            executor=executor,
            workers=workers,
            address=address,
            record=record,
            record_episodes=None if record_episodes < 0 else record_episodes,
            imports=mods,
            progress=progress,
            record_frames=record_frames,
        )
    typer.echo(
        f"{out}: ran {outcome.num_ran} episodes, skipped {outcome.num_skipped} already done",
        err=True,
    )
    if report:
        _report([out], out, plot=True, paper=suite == "paper", html=html)


def _runnable(
    envs_: list[str], agents_: list[str], args: list[str] | None
) -> list[tuple[str, str, dict[str, str]]]:
    """The (env, agent, agent args) pairs to run. ``all`` stands for every registered agent;
    pairs whose agent cannot run here are skipped with their reason when they came from ``all``,
    and are an error when the agent was named."""
    from kinder_bench.agents import unavailable_reason
    from kinder_bench.evaluation.envs import resolve_env_id

    named = [a for a in agents_ if a != "all"]
    expanded = list(dict.fromkeys(named + (list(AGENTS) if "all" in agents_ else [])))
    loadable = []
    for a in expanded:
        try:
            agent_class(a)
        except ValueError as err:  # e.g. a missing optional dependency
            if a in named:
                fail(str(err))
            typer.echo(f"skipping agent {a}: {err}", err=True)
            continue
        loadable.append(a)
    per_agent = parse_agent_args(args, loadable)
    pairs = []
    for a in loadable:
        for e in envs_:
            with user_errors():
                env_id = resolve_env_id(e)
            why = unavailable_reason(a, env_id, per_agent[a])
            if why is None:
                pairs.append((e, a, per_agent[a]))
            elif a in named:
                fail(f"agent {a} cannot run on {env_id} here: {why}")
            else:
                typer.echo(f"skipping {a} on {short_id(env_id)}: {why}", err=True)
    if not pairs:
        fail("no agent can run on these envs here (see the reasons above)")
    return pairs


def _suite_envs(suite: str | None) -> list[str]:
    if suite is None:
        return []
    if suite != "paper":
        fail(f"--suite {suite!r}: the only suite is 'paper'")
    from kinder_bench.evaluation.envs import known_env_ids
    from kinder_bench.evaluation.protocol import PAPER_ENVS

    known = set(known_env_ids())
    missing = [e for e in PAPER_ENVS if e not in known]
    if missing:
        typer.echo(f"--suite paper: skipping envs that are not installed: {missing}", err=True)
    return [e for e in PAPER_ENVS if e in known]


def _report(
    run_dirs: list[Path],
    out: Path | None,
    plot: bool,
    paper: bool = False,
    html: bool = False,
    first_episodes: int | None = None,
) -> None:
    from kinder_bench.reporting.report import write_report

    with user_errors():
        md, paths = write_report(
            run_dirs, out, plot=plot, paper=paper, html=html, first_episodes=first_episodes
        )
    typer.echo(md)
    typer.echo("wrote " + ", ".join(str(p) for p in paths.values()), err=True)


@bench_app.command("report")
def bench_report(
    run_dirs: Annotated[list[Path], typer.Argument(help="Run directories to aggregate.")],
    out: Annotated[
        Path | None, typer.Option(help="Where to write the report (default: the first run dir).")
    ] = None,
    plot: Annotated[bool, typer.Option(help="Also write success.png.")] = True,
    paper: Annotated[
        bool,
        typer.Option(
            help="Print and write the paper's Table II layout with the paper's value beside "
            "ours in every cell (paper_table.md, paper_comparison.csv)."
        ),
    ] = False,
    html: Annotated[
        bool, typer.Option(help="Also write report.html, one self-contained page.")
    ] = False,
    first_episodes: Annotated[
        int | None,
        typer.Option(
            help="Aggregate only the first N episodes of each seed (the same instances as a "
            "run of N episodes per seed); needs --out."
        ),
    ] = None,
) -> None:
    """Aggregate run directories: print the SR / Rwd / Inf-Time table, write CSV and a plot."""
    _report(run_dirs, out, plot, paper=paper, html=html, first_episodes=first_episodes)
