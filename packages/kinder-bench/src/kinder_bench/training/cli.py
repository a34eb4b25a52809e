"""``kinder train``: one command per learning baseline, each with the baseline's own options."""

from __future__ import annotations

import typer

train_app = typer.Typer(
    help="Train a learning baseline; evaluate it with `kinder bench run --agent NAME "
    "--arg checkpoint=DIR`.",
    no_args_is_help=True,
)


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
