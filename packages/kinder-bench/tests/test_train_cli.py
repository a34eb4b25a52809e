"""A trainer's argument dataclass is its command line: ``dataclass_command`` generates one option
per field and ``--arg FIELD=VALUE`` for any field; every ``kinder train`` command takes them."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

from kinder_bench.agents import build_dataclass
from kinder_bench.cli import app
from kinder_bench.cli.common import dataclass_command

runner = CliRunner()


@dataclasses.dataclass(frozen=True)
class ToyArgs:
    """A trainer's arguments."""

    out: Path
    """Where the run goes."""
    method: str = "a"
    """Set by the command."""
    steps: int = 10
    """Optimiser steps."""
    lr: float | None = None
    """Learning rate; None: the default schedule."""
    ema: bool = True
    """Keep an EMA."""
    env_id: str = "Motion2D-p0"
    """The env."""
    keep_steps: tuple[int, ...] = ()
    """Steps whose checkpoints are kept."""

    def __post_init__(self) -> None:
        if self.steps < 1:
            raise ValueError(f"steps must be >= 1, got {self.steps}")


def _toy_app() -> tuple[typer.Typer, list[tuple[ToyArgs, bool]]]:
    calls: list[tuple[ToyArgs, bool]] = []
    toy = typer.Typer()

    def run(args: Any, progress: bool) -> None:
        calls.append((args, progress))

    dataclass_command(
        toy, "toy", ToyArgs, run, help="Train the toy.", what="kinder train toy",
        fixed={"method": "b"}, flags={"env_id": ("--env", "-e")},
    )  # fmt: skip
    toy.command("other")(lambda: None)  # two commands: `toy` is then a subcommand
    return toy, calls


def test_every_field_is_an_option_with_its_type_default_and_docstring() -> None:
    toy, calls = _toy_app()
    result = runner.invoke(toy, ["toy", "--out", "o", "--steps", "3", "--no-ema", "-e", "X"])
    assert result.exit_code == 0, result.output
    (args, progress), = calls  # fmt: skip
    assert args == ToyArgs(out=Path("o"), method="b", steps=3, ema=False, env_id="X")
    assert progress is True
    runner.invoke(toy, ["toy", "--out", "o", "--lr", "0.5", "--no-progress"])
    assert calls[1][0].lr == 0.5 and calls[1][0].steps == 10 and calls[1][1] is False
    helptext = runner.invoke(toy, ["toy", "--help"]).output
    for text in ("--steps", "Optimiser steps", "--no-ema", "--env", "--arg", "--progress"):
        assert text in helptext
    assert "--method" not in helptext  # fixed by the command
    assert "--keep-steps" not in helptext  # a tuple: --arg only


def test_arg_sets_any_field_parsed_by_its_type() -> None:
    toy, calls = _toy_app()
    result = runner.invoke(
        toy, ["toy", "--out", "o", "--steps", "3", "--arg", "steps=7", "--arg", "keep_steps=[5,2]"]
    )
    assert result.exit_code == 0, result.output
    assert calls[0][0].steps == 7 and calls[0][0].keep_steps == [5, 2]


def test_bad_input_is_a_one_line_error() -> None:
    toy, calls = _toy_app()
    cases = {
        ("--arg", "steps"): "expected KEY=VALUE",
        ("--arg", "nope=1"): "Unknown argument(s) ['nope'] for kinder train toy",
        ("--arg", "method=c"): "set by `kinder train toy` itself",
        ("--arg", "steps=x"): "kinder train toy argument 'steps': cannot parse 'x'",
        ("--steps", "0"): "steps must be >= 1",
    }
    for extra, message in cases.items():
        result = runner.invoke(toy, ["toy", "--out", "o", *extra])
        assert result.exit_code == 2 and message in result.output, (extra, result.output)
    assert runner.invoke(toy, ["toy"]).exit_code != 0  # --out is required
    assert not calls


def test_build_dataclass_names_what_is_wrong() -> None:
    built = build_dataclass(ToyArgs, {"out": "o", "ema": "false", "lr": "none"}, "x")
    assert built == ToyArgs(out=Path("o"), ema=False, lr=None)
    unknown = r"\['step'\] for kinder train toy; its arguments: .*'steps'"
    with pytest.raises(ValueError, match=unknown):
        build_dataclass(ToyArgs, {"out": "o", "step": "3"}, "kinder train toy")


def test_every_trainer_takes_its_fields_as_options_and_arg() -> None:
    for method, fields in {
        "dp": ("--dataset", "--steps", "--warmup-steps", "--keep", "--no-ema"),
        "dpes": ("--dataset", "--preset", "--num-workers"),
        "mbrl": ("--epochs", "--val-fraction", "--hidden", "--keep"),
        "gsc": ("--env", "--demo-episodes", "--perturb-noise", "--classifier-depth"),
        "ppo": ("--env", "--seed", "--steps", "--hp"),
        "sac": ("--env", "--n-envs", "--hp"),
    }.items():
        result = runner.invoke(app, ["train", method, "--help"], terminal_width=200)
        assert result.exit_code == 0, result.output
        for text in (*fields, "--arg", "--progress"):
            assert text in result.output, (method, text)
    assert "--method" not in runner.invoke(app, ["train", "dpes", "--help"]).output
    bad = runner.invoke(app, ["train", "dp", "--dataset", "d", "--out", "o", "--arg", "x=1"])
    assert bad.exit_code == 2 and "Unknown argument(s) ['x'] for kinder train dp" in bad.output
