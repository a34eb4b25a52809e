"""``kinder train``: one command per learning baseline; a trainer's argument dataclass is its
command line.

Every trainer takes every field of its dataclass as ``--arg FIELD=VALUE``, parsed by the field's
type as an agent's ``--arg`` is (:func:`~kinder_bench.agents.build_dataclass`). DP and DPES
(:class:`~kinder_bench.baselines.diffusion.DiffusionTrainArgs`), MBRL
(:class:`~kinder_bench.baselines.mbrl.MBRLTrainArgs`) and GSC
(:class:`~kinder_bench.baselines.gsc.config.GSCTrainConfig`) also take each field as an option
``--field-name``, generated from the dataclass (:func:`~kinder_bench.cli.common.dataclass_command`).
PPO and SAC name their common fields as options here (``--env``, ``--seed``, ``--steps``, ...):
their dataclasses live beside Stable-Baselines3, which the command line does not import until a
PPO or SAC command runs; ``--hp`` is another name of their ``--arg``.

The trainers' shared library (checkpoints, CSV logs) is :mod:`kinder_bench.training`."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from kinder_bench.baselines.diffusion import DiffusionTrainArgs
from kinder_bench.baselines.gsc.config import GSCTrainConfig
from kinder_bench.baselines.mbrl import MBRLTrainArgs
from kinder_bench.cli.common import (
    ProgressOpt,
    dataclass_command,
    parse_key_values,
    parse_seeds,
    user_errors,
)

train_app = typer.Typer(
    help="Train a learning baseline; evaluate it with `kinder bench run --agent NAME "
    "--arg checkpoint=DIR`.",
    no_args_is_help=True,
)


def _run_diffusion(args: DiffusionTrainArgs, progress: bool) -> None:
    import torch

    from kinder_bench.baselines.diffusion import train_diffusion

    if args.device != "cuda":
        torch.set_num_threads(max(1, min(torch.get_num_threads(), 4)))
    ckpt = train_diffusion(args, progress=progress)
    typer.echo(f"checkpoint: {ckpt}")
    typer.echo(
        f"evaluate:   kinder bench run --env ENV --agent {args.method} --arg checkpoint={args.out}"
    )


for _method, _help in (
    (
        "dp",
        "Diffusion policy on images + robot state (lerobot DiffusionPolicy, the paper's config).",
    ),
    ("dpes", "Diffusion policy on images + robot state + environment state (normalised)."),
):
    dataclass_command(
        train_app, _method, DiffusionTrainArgs, _run_diffusion, help=_help,
        what=f"kinder train {_method}", fixed={"method": _method},
    )  # fmt: skip


def _run_mbrl(args: MBRLTrainArgs, progress: bool) -> None:
    import torch

    from kinder_bench.baselines.mbrl import train_mbrl

    torch.set_num_threads(max(1, min(torch.get_num_threads(), 4)))
    ckpt = train_mbrl(args, progress=progress)
    evaluation = json.loads((args.out / "eval.json").read_text())
    typer.echo(f"checkpoint: {ckpt}")
    for k in (1, 10):
        if f"model_l2_{k}" in evaluation:
            e = {n: evaluation[f"{n}_{k}"] for n in ("model_l2", "model_z", "const_l2", "const_z")}
            typer.echo(
                f"held-out {k}-step open-loop error: model {e['model_l2']:.4g} (z "
                f"{e['model_z']:.3g}), constant-state {e['const_l2']:.4g} (z {e['const_z']:.3g}) "
                f"over {int(evaluation[f'count_{k}'])} starts"
            )
    typer.echo(f"evaluate:   kinder bench run --env ENV --agent mbrl --arg checkpoint={args.out}")


dataclass_command(
    train_app,
    "mbrl",
    MBRLTrainArgs,
    _run_mbrl,
    help="MBRL: the state-delta model that the `mbrl` agent's MPC rolls out; prints its "
    "held-out one-step and 10-step open-loop errors.",
    what="kinder train mbrl",
)


def _run_gsc(config: GSCTrainConfig, progress: bool) -> None:
    from kinder_bench.baselines.gsc.train import train_gsc
    from kinder_bench.training.checkpoints import latest_checkpoint

    train_gsc(config, show_progress=progress)
    typer.echo(f"checkpoint: {latest_checkpoint(config.out)}")
    typer.echo(f"evaluate:   kinder bench run --env ENV --agent gsc --arg checkpoint={config.out}")


dataclass_command(
    train_app,
    "gsc",
    GSCTrainConfig,
    _run_gsc,
    help="Generative skill chaining: per-skill diffusion models and feasibility classifiers. "
    "Evaluate with `kinder bench run --env ENV --agent gsc --arg checkpoint=OUT`.",
    what="kinder train gsc",
    flags={"env_id": ("--env", "-e"), "out": ("--out", "-o")},
)


@train_app.command("ood")
def ood_command(
    checkpoint: Annotated[Path, typer.Option(help="A DP run (trained on DynObstruction2D-o1).")],
    out: Annotated[Path, typer.Option(help="Run directory of the evaluation (resumable).")],
    agent: Annotated[str, typer.Option(help="dp (the paper's), or dpes (fails on o0).")] = "dp",
    seeds: Annotated[str, typer.Option(help="Run seeds, e.g. 0-4.")] = "0-4",
    episodes: Annotated[int, typer.Option(help="Episodes per seed.")] = 50,
    workers: Annotated[int | None, typer.Option(help="Worker processes.")] = None,
    executor: Annotated[str, typer.Option(help="process, inline or ray.")] = "process",
    device: Annotated[str, typer.Option(help="Where the policy runs: cpu, cuda, auto.")] = "cpu",
    progress: ProgressOpt = True,
) -> None:
    """The paper's OOD test: a policy trained on DynObstruction2D-o1 evaluated on o0-o3."""
    from kinder_bench.baselines.ood import OOD_ENVS, run_ood

    with user_errors():
        table = run_ood(
            checkpoint, out, agent=agent, seeds=parse_seeds(seeds), episodes=episodes,
            workers=workers, executor=executor, progress=progress, device=device,
        )  # fmt: skip
    typer.echo(f"OOD evaluation on {', '.join(OOD_ENVS)}:")
    typer.echo(table)


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
    values: dict[str, object] = {
        "env_id": env,
        "seed": seed,
        "total_steps": steps,
        "n_envs": n_envs,
        "vec_env": vec_env,
        "reward": reward,
        "checkpoint_every": checkpoint_every,
    }
    values.update(parse_key_values(hp, "--arg"))
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


RLEnvOpt = Annotated[str, typer.Option("--env", "-e", help="Environment id.")]
RLSeedOpt = Annotated[int, typer.Option(help="Training seed (networks, learner and envs).")]
RLStepsOpt = Annotated[int, typer.Option(help="Env steps in total (the paper: 1M).")]
RLOutOpt = Annotated[
    Path, typer.Option(help="Output directory; rerunning with it resumes from its checkpoint.")
]
NEnvsOpt = Annotated[
    int | None, typer.Option(help="Vector envs (default: the paper's, 8 or 16 per env).")
]
VecOpt = Annotated[
    str,
    typer.Option(
        help="'dummy' (in process), 'subproc' (one process each) or 'batched' (Kinematic2D: "
        "all envs in whole numpy arrays, same results as 'dummy')."
    ),
]
RewardOpt = Annotated[
    str, typer.Option(help="'sparse' (the env's) or 'dense' (BaseMotion3D's shaping).")
]
CkptOpt = Annotated[int, typer.Option(help="Checkpoint every N env steps (and at the end).")]
HpOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--arg",
        "--hp",
        help="Any argument FIELD=VALUE of PPOArgs/SACArgs, parsed by the field's type (e.g. "
        "hidden_size=64, learning_rate=1e-3, keep_steps=[1000,2000]); overrides the option of "
        "that name; see kinder_bench.baselines.rl.train. Repeatable.",
    ),
]


@train_app.command("ppo")
def train_ppo(
    env: RLEnvOpt = "Motion2D-p0",
    seed: RLSeedOpt = 0,
    steps: RLStepsOpt = 1_000_000,
    out: RLOutOpt = Path("runs/train/ppo"),
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
    env: RLEnvOpt = "Motion2D-p0",
    seed: RLSeedOpt = 0,
    steps: RLStepsOpt = 1_000_000,
    out: RLOutOpt = Path("runs/train/sac"),
    n_envs: NEnvsOpt = None,
    vec_env: VecOpt = "dummy",
    reward: RewardOpt = "sparse",
    checkpoint_every: CkptOpt = 50_000,
    hp: HpOpt = None,
    progress: ProgressOpt = True,
) -> None:
    """SAC with the paper's settings (Stable-Baselines3, the rl extra)."""
    _train_rl("sac", env, seed, steps, out, n_envs, vec_env, reward, checkpoint_every, hp, progress)
