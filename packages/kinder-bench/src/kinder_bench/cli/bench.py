"""The ``kinder`` command line: list and show envs, roll out agents, run and report benchmarks."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any, NoReturn

import numpy as np
import typer

import kinder_core
from kinder_bench.agents import AGENTS, agent_class, describe_args
from kinder_bench.demos_cli import demos_app
from kinder_bench.envs import short_id
from kinder_bench.executors import EXECUTORS
from kinder_bench.recording import VIDEO_FORMATS
from kinder_bench.serve_cli import serve_cmd
from kinder_bench.teleop_cli import teleop_cmd
from kinder_bench.training.cli import train_app

app = typer.Typer(
    name="kinder",
    help="KinDER: physical-reasoning environments and the KinDERBench evaluation runner.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
bench_app = typer.Typer(help="Run benchmarks and report their results.", no_args_is_help=True)
app.add_typer(bench_app, name="bench")
app.add_typer(train_app, name="train")
app.add_typer(demos_app, name="demos")
app.command("teleop")(teleop_cmd)
app.command("serve")(serve_cmd)

ImportOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--import",
        help="Module to import first (and in every worker), e.g. one that registers extra envs "
        "or agents. Repeatable.",
    ),
]
ArgOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--arg",
        help="Agent argument KEY=VALUE (AGENT.KEY=VALUE to target one agent); see `kinder "
        "agents`. Repeatable.",
    ),
]


def fail(message: str) -> NoReturn:
    """Print an error to stderr and exit with status 2."""
    typer.secho(f"Error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(2)


@contextlib.contextmanager
def user_errors() -> Iterator[None]:
    """Turn the errors a user can fix into a one-line message instead of a traceback."""
    try:
        yield
    except (ValueError, ModuleNotFoundError, FileNotFoundError, ImportError) as e:
        fail(str(e))


def _import(modules: list[str] | None) -> tuple[str, ...]:
    from kinder_bench.runner import import_modules

    mods = tuple(modules or ())
    with user_errors():
        import_modules(mods)
    return mods


def parse_seeds(text: str) -> tuple[int, ...]:
    """``"0-4"`` → (0, 1, 2, 3, 4); ``"0,2,7"`` → (0, 2, 7); ranges and lists combine."""
    seeds: list[int] = []
    try:
        for part in filter(None, (p.strip() for p in text.split(","))):
            lo, sep, hi = part.partition("-")
            if sep and int(hi) < int(lo):
                raise ValueError(part)
            seeds += range(int(lo), int(hi) + 1) if sep else [int(part)]
    except ValueError:
        fail(f"--seeds: cannot parse {text!r}; expected non-negative seeds like '0-4' or '0,1,2'")
    if not seeds:
        fail(f"--seeds: no seeds in {text!r}")
    return tuple(dict.fromkeys(seeds))


def parse_agent_args(items: list[str] | None, agents: list[str]) -> dict[str, dict[str, str]]:
    """``KEY=VALUE`` applies to every listed agent that has KEY; ``AGENT.KEY=VALUE`` to one."""
    out: dict[str, dict[str, str]] = {a: {} for a in agents}
    fields: dict[str, set[str]] = {}
    for a in agents:
        with user_errors():
            fields[a] = {name for name, *_ in describe_args(agent_class(a))}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            fail(f"--arg {item!r}: expected KEY=VALUE or AGENT.KEY=VALUE")
        agent, dot, name = key.rpartition(".")
        if dot and agent in out:
            targets = [agent]
        elif dot:
            fail(f"--arg {item!r}: agent {agent!r} is not among the agents {agents}")
        else:
            name = key
            targets = [a for a in agents if name in fields[a]]
        targets = [a for a in targets if name in fields[a]]
        if not targets:
            known = {a: sorted(f) for a, f in fields.items()}
            fail(f"--arg {item!r}: no agent here has an argument {name!r}; arguments: {known}")
        for a in targets:
            out[a][name] = value
    return out


@app.command()
def envs(
    category: Annotated[
        str | None,
        typer.Option("--category", "-c", help="Kinematic2D, Dynamic2D, Kinematic3D or Dynamic3D."),
    ] = None,
    imports: ImportOpt = None,
) -> None:
    """List the registered environment ids (of the installed packages)."""
    import gymnasium

    from kinder_bench.envs import known_env_ids

    _import(imports)
    with user_errors():
        if category is not None:
            import kinder_core

            ids = kinder_core.list_envs(category)
        else:
            ids = known_env_ids()
    if not ids:
        typer.echo("No environments registered" + (f" in {category}" if category else "") + ".")
        return
    width = max(len(i) for i in ids)
    for env_id in ids:
        steps = gymnasium.spec(env_id).max_episode_steps
        typer.echo(f"{env_id:<{width}}  max_steps={steps}")


@app.command()
def agents() -> None:
    """List the agents, their arguments (defaults and meaning) and, where an agent cannot run on
    the paper's envs here with its defaults, why."""
    from kinder_bench.agents import unavailable_reason
    from kinder_bench.protocol import PAPER_ENVS

    for name in AGENTS:
        try:
            cls = agent_class(name)
        except ValueError as e:  # e.g. an optional dependency is missing
            typer.echo(f"{name}  (unavailable: {e})")
            continue
        doc = (cls.__doc__ or "").strip().splitlines()[0]
        typer.secho(f"{name}", bold=True, nl=False)
        typer.echo(f"  {doc}")
        for arg, type_name, default, help_ in describe_args(cls):
            typer.echo(f"    {arg}: {type_name} = {default!r}  {help_}")
        # Whether it can run here with its defaults, on the paper's envs.
        reasons: dict[str, list[str]] = {}
        for env_id in PAPER_ENVS:
            why = unavailable_reason(name, env_id)
            if why is not None:
                reasons.setdefault(why, []).append(short_id(env_id))
        for why, where in reasons.items():
            typer.echo(f"    cannot run here on {', '.join(where)}: {why}")


@app.command()
def show(
    env_id: Annotated[str, typer.Argument(help="Environment id, e.g. kinder/Motion2D-p0-v0.")],
    seed: Annotated[int, typer.Option(help="Seed of env.reset.")] = 0,
    out: Annotated[Path | None, typer.Option(help="Write the initial state's image (PNG).")] = None,
    imports: ImportOpt = None,
) -> None:
    """Describe an environment and print a seeded initial state (optionally save its image)."""
    from kinder_bench.envs import default_max_steps, make_env, resolve_env_id

    _import(imports)
    with user_errors():
        env_id = resolve_env_id(env_id)
        env = make_env(env_id)
    env.reset(seed=seed)
    model: Any = env.unwrapped
    meta = env.unwrapped.metadata
    typer.secho(env_id, bold=True)
    description = str(meta.get("description", "")).strip()
    if description:
        typer.echo(description)
    typer.echo(
        f"observation: Box{tuple(env.observation_space.shape or ())}   action: "
        f"{env.action_space}   max_steps: {default_max_steps(env_id)}"
    )
    typer.echo(f"initial state (seed {seed}):")
    typer.echo(model.get_state().pretty())
    if out is not None:
        import imageio.v2 as imageio

        frame = np.asarray(env.render())
        out.parent.mkdir(parents=True, exist_ok=True)
        imageio.imwrite(out, frame)
        typer.echo(f"wrote {out}")
    env.close()


@app.command()
def rollout(
    env_id: Annotated[str, typer.Argument(help="Environment id, e.g. kinder/Motion2D-p0-v0.")],
    agent: Annotated[str, typer.Option(help="Agent name (see `kinder agents`).")] = "random",
    args: ArgOpt = None,
    seed: Annotated[int, typer.Option(help="Run seed: the episode is episode 0 of this seed.")] = 0,
    max_steps: Annotated[int | None, typer.Option(help="Step budget (default: the env's).")] = None,
    gif: Annotated[Path | None, typer.Option(help="Record the episode (.gif or .mp4).")] = None,
    imports: ImportOpt = None,
) -> None:
    """Run one episode of an agent and print its result."""
    from kinder_bench.runner import RunConfig, make_tasks, resolve_run, run_episode

    mods = _import(imports)
    agent_args = parse_agent_args(args, [agent])[agent]
    with user_errors():
        run = resolve_run(RunConfig(env_id, agent, agent_args, (seed,), 1, max_steps))
    task = make_tasks(run, imports=mods)[0]
    if gif is not None:
        task = type(task)(**{**task.__dict__, "video_path": str(gif)})
    rec = run_episode(task)
    status = "success" if rec["success"] else "failure"
    typer.echo(
        f"{run.env_id}  agent={agent}  seed={seed} (env seed {rec['env_seed']}): {status} in "
        f"{rec['steps']} steps, reward {rec['reward']:.1f}, inference {rec['inference_time']:.3f}"
        f" s, env {rec['env_time']:.3f} s"
    )
    if rec["error"]:
        typer.secho(
            f"episode error ({rec['error_in']}): {rec['error']}", fg=typer.colors.RED, err=True
        )
    if rec.get("video_error"):
        fail(rec["video_error"])
    if rec["video"]:
        typer.echo(f"wrote {rec['video']}")


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
            "column beside the paper's."
        ),
    ] = None,
    imports: ImportOpt = None,
) -> None:
    """Run every agent on every env over the seeds (resuming what the run directory has).

    With ``--suite paper`` the report at the end is the paper comparison (Table II's layout)."""
    from kinder_bench.runner import RunConfig, run_benchmark

    mods = _import(imports)
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
        RunConfig(e, a, a_args, seed_list, episodes, max_steps, label=label)
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
    from kinder_bench.envs import resolve_env_id

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
    from kinder_bench.envs import known_env_ids
    from kinder_bench.protocol import PAPER_ENVS

    known = set(known_env_ids())
    missing = [e for e in PAPER_ENVS if e not in known]
    if missing:
        typer.echo(f"--suite paper: skipping envs that are not installed: {missing}", err=True)
    return [e for e in PAPER_ENVS if e in known]


def _report(
    run_dirs: list[Path], out: Path | None, plot: bool, paper: bool = False, html: bool = False
) -> None:
    from kinder_bench.report import write_report

    with user_errors():
        md, paths = write_report(run_dirs, out, plot=plot, paper=paper, html=html)
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
) -> None:
    """Aggregate run directories: print the SR / Rwd / Inf-Time table, write CSV and a plot."""
    _report(run_dirs, out, plot, paper=paper, html=html)


@app.command()
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


def main() -> None:
    """Entry point for ``python -m kinder_bench``."""
    app(prog_name="kinder")


if __name__ == "__main__":
    main()
