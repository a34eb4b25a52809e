"""What every ``kinder`` command group shares: the error exit, user-error handling, ``--import``,
``--seeds`` and ``--arg`` parsing.

This module imports no other module of :mod:`kinder_bench.cli`, so each command group imports it
and the root app (:mod:`kinder_bench.cli.kinder`) imports the groups: no import circle.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Annotated, NoReturn

import typer

from kinder_bench.agents import agent_class, describe_args

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


def load_imports(modules: list[str] | None) -> tuple[str, ...]:
    """Import the ``--import`` modules here (a bad name is a user error); returns them for the
    runner's workers to import too."""
    from kinder_bench.evaluation.runner import import_modules

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
