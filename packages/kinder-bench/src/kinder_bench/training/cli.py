"""``kinder train``: one command per learning baseline, each with the baseline's own options."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

train_app = typer.Typer(
    help="Train a learning baseline; evaluate it with `kinder bench run --agent NAME "
    "--arg checkpoint=DIR`.",
    no_args_is_help=True,
)


def _train_rl(
    algo: str,
    env: str,
    seed: int,
    steps: int,
    out: Path,
    n_envs: int | None,
    vec_env: str,
    reward: str,
    checkpoint_every: int,
    hp: list[str] | None,
    progress: bool,
) -> None:
    from kinder_bench.cli import fail, user_errors

    values: dict[str, object] = {
        "env_id": env,
        "seed": seed,
        "total_steps": steps,
        "n_envs": n_envs,
        "vec_env": vec_env,
        "reward": reward,
        "checkpoint_every": checkpoint_every,
    }
    for item in hp or []:
        key, sep, value = item.partition("=")
        if not sep:
            fail(f"--hp {item!r}: expected KEY=VALUE")
        values[key.strip()] = value.strip()
    with user_errors():
        from kinder_bench.baselines.rl.train import make_train_args, train

        args = make_train_args(algo, values)
        result = train(algo, args, out, progress=progress)
    if result.ran_steps == 0:
        typer.echo(f"{out}: already trained ({result.steps} steps); {result.checkpoint}", err=True)
    else:
        resumed = f", resumed from {result.resumed_from}" if result.resumed_from else ""
        typer.echo(
            f"{out}: trained {result.ran_steps} steps in {result.wall_s:.0f} s "
            f"({result.ran_steps / max(result.wall_s, 1e-9):.0f} steps/s{resumed}); "
            f"checkpoint {result.checkpoint}",
            err=True,
        )
    typer.echo(f"evaluate: kinder bench run --env {env} --agent {algo} --arg checkpoint={out}")


EnvOpt = Annotated[str, typer.Option("--env", "-e", help="Environment id.")]
SeedOpt = Annotated[int, typer.Option(help="Training seed (networks, learner and envs).")]
StepsOpt = Annotated[int, typer.Option(help="Env steps in total (the paper: 1M).")]
OutOpt = Annotated[
    Path, typer.Option(help="Output directory; rerunning with it resumes from its checkpoint.")
]
NEnvsOpt = Annotated[
    int | None, typer.Option(help="Vector envs (default: the paper's, 8 or 16 per env).")
]
VecOpt = Annotated[str, typer.Option(help="'dummy' (in process) or 'subproc' (one process each).")]
RewardOpt = Annotated[
    str, typer.Option(help="'sparse' (the env's) or 'dense' (BaseMotion3D's shaping).")
]
CkptOpt = Annotated[int, typer.Option(help="Checkpoint every N env steps (and at the end).")]
HpOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--hp",
        help="Any other argument KEY=VALUE of PPOArgs/SACArgs (e.g. hidden_size=64, "
        "learning_rate=1e-3); see kinder_bench.baselines.rl.train. Repeatable.",
    ),
]
ProgressOpt = Annotated[bool, typer.Option(help="Show a progress bar.")]


@train_app.command("ppo")
def train_ppo(
    env: EnvOpt = "Motion2D-p0",
    seed: SeedOpt = 0,
    steps: StepsOpt = 1_000_000,
    out: OutOpt = Path("runs/train/ppo"),
    n_envs: NEnvsOpt = None,
    vec_env: VecOpt = "dummy",
    reward: RewardOpt = "sparse",
    checkpoint_every: CkptOpt = 50_000,
    hp: HpOpt = None,
    progress: ProgressOpt = True,
) -> None:
    """PPO with the paper's settings (Stable-Baselines3, the rl extra)."""
    _train_rl("ppo", env, seed, steps, out, n_envs, vec_env, reward, checkpoint_every, hp, progress)


@train_app.command("sac")
def train_sac(
    env: EnvOpt = "Motion2D-p0",
    seed: SeedOpt = 0,
    steps: StepsOpt = 1_000_000,
    out: OutOpt = Path("runs/train/sac"),
    n_envs: NEnvsOpt = None,
    vec_env: VecOpt = "dummy",
    reward: RewardOpt = "sparse",
    checkpoint_every: CkptOpt = 50_000,
    hp: HpOpt = None,
    progress: ProgressOpt = True,
) -> None:
    """SAC with the paper's settings (Stable-Baselines3, the rl extra)."""
    _train_rl("sac", env, seed, steps, out, n_envs, vec_env, reward, checkpoint_every, hp, progress)
