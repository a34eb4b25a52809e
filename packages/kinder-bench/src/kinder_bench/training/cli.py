"""``kinder train``: one command per learning baseline, each with the baseline's own options."""

from __future__ import annotations

import typer

train_app = typer.Typer(
    help="Train a learning baseline; evaluate it with `kinder bench run --agent NAME "
    "--arg checkpoint=DIR`.",
    no_args_is_help=True,
)
