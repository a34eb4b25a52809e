"""``kinder envs``, ``show``, ``agents`` and ``rollout``: one environment or agent at a time."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from kinder_bench.agents import AGENTS, agent_class, describe_args
from kinder_bench.cli.common import (
    ArgOpt,
    ImportOpt,
    fail,
    load_imports,
    parse_agent_args,
    user_errors,
)
from kinder_bench.evaluation.envs import short_id


def envs(
    category: Annotated[
        str | None,
        typer.Option("--category", "-c", help="Kinematic2D, Dynamic2D, Kinematic3D or Dynamic3D."),
    ] = None,
    imports: ImportOpt = None,
) -> None:
    """List the registered environment ids (of the installed packages)."""
    import gymnasium

    from kinder_bench.evaluation.envs import known_env_ids

    load_imports(imports)
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


def agents() -> None:
    """List the agents, their arguments (defaults and meaning) and, where an agent cannot run on
    the paper's envs here with its defaults, why."""
    from kinder_bench.agents import unavailable_reason
    from kinder_bench.evaluation.protocol import PAPER_ENVS

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


def show(
    env_id: Annotated[str, typer.Argument(help="Environment id, e.g. kinder/Motion2D-p0-v0.")],
    seed: Annotated[int, typer.Option(help="Seed of env.reset.")] = 0,
    out: Annotated[Path | None, typer.Option(help="Write the initial state's image (PNG).")] = None,
    imports: ImportOpt = None,
) -> None:
    """Describe an environment and print a seeded initial state (optionally save its image)."""
    from kinder_bench.evaluation.envs import default_max_steps, make_env, resolve_env_id

    load_imports(imports)
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
    from kinder_bench.evaluation.runner import RunConfig, make_tasks, resolve_run, run_episode

    mods = load_imports(imports)
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
