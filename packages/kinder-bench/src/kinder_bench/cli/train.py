"""``kinder train``: one command per learning baseline, each with the baseline's own options.

The trainers' shared library (checkpoints, CSV logs) is :mod:`kinder_bench.training`."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from kinder_bench.cli.common import fail, parse_seeds, user_errors

train_app = typer.Typer(
    help="Train a learning baseline; evaluate it with `kinder bench run --agent NAME "
    "--arg checkpoint=DIR`.",
    no_args_is_help=True,
)


DatasetOpt = Annotated[Path, typer.Option(help="The demonstration dataset (LeRobot v3 directory).")]
OutOpt = Annotated[
    Path,
    typer.Option(
        help="Run directory; rerunning with the same one resumes from its last checkpoint."
    ),
]
EnvOpt = Annotated[str | None, typer.Option(help="Env id (default: the one the dataset names).")]
SeedOpt = Annotated[int, typer.Option(help="Seed of the weights, the sample order and the noise.")]
ProgressOpt = Annotated[bool, typer.Option("--progress/--no-progress", help="Show a progress bar.")]


def _diffusion(
    method: str,
    dataset: Path,
    out: Path,
    steps: int,
    preset: str,
    batch_size: int | None,
    lr: float,
    warmup_steps: int,
    env: str | None,
    save_every: int,
    log_every: int,
    seed: int,
    device: str,
    num_workers: int,
    ema: bool,
    progress: bool,
) -> None:
    with user_errors():
        import torch

        from kinder_bench.baselines.diffusion import DiffusionTrainArgs, train_diffusion

        args = DiffusionTrainArgs(
            dataset=dataset, out=out, method=method, steps=steps, preset=preset,
            batch_size=batch_size, lr=lr, warmup_steps=warmup_steps, env=env,
            save_every=save_every, log_every=log_every, seed=seed, device=device,
            num_workers=num_workers, ema=ema,
        )  # fmt: skip
        if args.device != "cuda":
            torch.set_num_threads(max(1, min(torch.get_num_threads(), 4)))
        ckpt = train_diffusion(args, progress=progress)
    typer.echo(f"checkpoint: {ckpt}")
    typer.echo(f"evaluate:   kinder bench run --env ENV --agent {method} --arg checkpoint={out}")


StepsOpt = Annotated[int, typer.Option(help="Optimiser steps in total.")]
PresetOpt = Annotated[
    str, typer.Option(help="paper (the paper's model) or cpu (small, smoke runs).")
]
BatchOpt = Annotated[int | None, typer.Option(help="Batch size (default: paper 64, cpu 16).")]
LrOpt = Annotated[float, typer.Option(help="Peak AdamW learning rate.")]
WarmupOpt = Annotated[int, typer.Option(help="Linear warm-up steps.")]
SaveOpt = Annotated[int, typer.Option(help="Checkpoint every this many steps.")]
LogOpt = Annotated[int, typer.Option(help="Log to progress.csv every this many steps.")]
DeviceOpt = Annotated[str, typer.Option(help="cpu, cuda or auto.")]
WorkersOpt = Annotated[int, typer.Option(help="Data-loading worker processes.")]
EmaOpt = Annotated[bool, typer.Option("--ema/--no-ema", help="Keep an EMA of the weights.")]


@train_app.command("dp")
def train_dp(
    dataset: DatasetOpt,
    out: OutOpt,
    steps: StepsOpt = 100_000,
    preset: PresetOpt = "paper",
    batch_size: BatchOpt = None,
    lr: LrOpt = 1e-4,
    warmup_steps: WarmupOpt = 500,
    env: EnvOpt = None,
    save_every: SaveOpt = 1000,
    log_every: LogOpt = 100,
    seed: SeedOpt = 0,
    device: DeviceOpt = "auto",
    num_workers: WorkersOpt = 0,
    ema: EmaOpt = True,
    progress: ProgressOpt = True,
) -> None:
    """Diffusion policy on images + robot state (lerobot DiffusionPolicy, the paper's config)."""
    _diffusion("dp", dataset, out, steps, preset, batch_size, lr, warmup_steps, env, save_every,
               log_every, seed, device, num_workers, ema, progress)  # fmt: skip


@train_app.command("dpes")
def train_dpes(
    dataset: DatasetOpt,
    out: OutOpt,
    steps: StepsOpt = 100_000,
    preset: PresetOpt = "paper",
    batch_size: BatchOpt = None,
    lr: LrOpt = 1e-4,
    warmup_steps: WarmupOpt = 500,
    env: EnvOpt = None,
    save_every: SaveOpt = 1000,
    log_every: LogOpt = 100,
    seed: SeedOpt = 0,
    device: DeviceOpt = "auto",
    num_workers: WorkersOpt = 0,
    ema: EmaOpt = True,
    progress: ProgressOpt = True,
) -> None:
    """Diffusion policy on images + robot state + environment state (normalised)."""
    _diffusion("dpes", dataset, out, steps, preset, batch_size, lr, warmup_steps, env, save_every,
               log_every, seed, device, num_workers, ema, progress)  # fmt: skip


@train_app.command("mbrl")
def train_mbrl_command(
    dataset: DatasetOpt,
    out: OutOpt,
    epochs: Annotated[int, typer.Option(help="Passes over the training transitions.")] = 1000,
    batch_size: Annotated[int, typer.Option(help="Transitions per step.")] = 512,
    lr: Annotated[float, typer.Option(help="Adam learning rate.")] = 1e-3,
    val_fraction: Annotated[float, typer.Option(help="Fraction of episodes held out.")] = 0.1,
    env: EnvOpt = None,
    save_every: Annotated[int, typer.Option(help="Checkpoint every this many epochs.")] = 50,
    seed: SeedOpt = 0,
    progress: ProgressOpt = True,
) -> None:
    """MBRL: the state-delta model that the `mbrl` agent's MPC rolls out; prints its held-out
    one-step and 10-step open-loop errors."""
    with user_errors():
        import torch

        from kinder_bench.baselines.mbrl import MBRLTrainArgs, train_mbrl

        torch.set_num_threads(max(1, min(torch.get_num_threads(), 4)))
        args = MBRLTrainArgs(
            dataset=dataset, out=out, epochs=epochs, batch_size=batch_size, lr=lr,
            val_fraction=val_fraction, env=env, save_every=save_every, seed=seed,
        )  # fmt: skip
        ckpt = train_mbrl(args, progress=progress)
    evaluation = json.loads((out / "eval.json").read_text())
    typer.echo(f"checkpoint: {ckpt}")
    for k in (1, 10):
        if f"model_l2_{k}" in evaluation:
            e = {n: evaluation[f"{n}_{k}"] for n in ("model_l2", "model_z", "const_l2", "const_z")}
            typer.echo(
                f"held-out {k}-step open-loop error: model {e['model_l2']:.4g} (z "
                f"{e['model_z']:.3g}), constant-state {e['const_l2']:.4g} (z {e['const_z']:.3g}) "
                f"over {int(evaluation[f'count_{k}'])} starts"
            )
    typer.echo(f"evaluate:   kinder bench run --env ENV --agent mbrl --arg checkpoint={out}")


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


@train_app.command("gsc")
def train_gsc_command(
    env: str = typer.Option(..., "--env", "-e", help="The env id, e.g. StickButton2D-b1."),
    out: str = typer.Option(..., "--out", "-o", help="Checkpoint directory (resumed if present)."),
    dataset: str | None = typer.Option(
        None, "--dataset", help="LeRobot dataset or demo collection; default: collect BP demos."
    ),
    demo_episodes: int = typer.Option(50, help="BP demos to generate without --dataset."),
    demo_seed: int = typer.Option(1000, help="Collection seed of the BP demos (not 0-4: eval)."),
    perturbations: int = typer.Option(4, help="Perturbed executions per demo skill."),
    steps: int = typer.Option(2000, help="Optimisation steps (every skill per step)."),
    batch_size: int = typer.Option(128),
    lr: float = typer.Option(1e-3),
    hidden: int = typer.Option(128, help="Width of the ε-network."),
    depth: int = typer.Option(3, help="Residual blocks of the ε-network."),
    checkpoint_every: int = typer.Option(500),
    seed: int = typer.Option(0),
    threads: int = typer.Option(1, help="torch.set_num_threads."),
    progress: bool = typer.Option(True, help="Show progress bars."),
) -> None:
    """Generative skill chaining: per-skill diffusion models and feasibility classifiers.

    Evaluate with `kinder bench run --env ENV --agent gsc --arg checkpoint=OUT`.
    """
    from kinder_bench.baselines.gsc.train import GSCTrainConfig, train_gsc

    config = GSCTrainConfig(
        env_id=env,
        out=out,
        dataset=dataset,
        demo_episodes=demo_episodes,
        demo_seed=demo_seed,
        perturbations=perturbations,
        steps=steps,
        batch_size=batch_size,
        lr=lr,
        hidden=hidden,
        depth=depth,
        checkpoint_every=checkpoint_every,
        seed=seed,
        threads=threads,
    )
    try:
        train_gsc(config, show_progress=progress)
    except (ValueError, FileNotFoundError, ImportError) as e:
        typer.echo(f"Error: {e}", err=True)
        raise typer.Exit(2) from e
    typer.echo(f"GSC model written to {out}/model.pt")


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
        "--hp",
        help="Any other argument KEY=VALUE of PPOArgs/SACArgs (e.g. hidden_size=64, "
        "learning_rate=1e-3); see kinder_bench.baselines.rl.train. Repeatable.",
    ),
]
RLProgressOpt = Annotated[bool, typer.Option(help="Show a progress bar.")]


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
    progress: RLProgressOpt = True,
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
    progress: RLProgressOpt = True,
) -> None:
    """SAC with the paper's settings (Stable-Baselines3, the rl extra)."""
    _train_rl("sac", env, seed, steps, out, n_envs, vec_env, reward, checkpoint_every, hp, progress)
