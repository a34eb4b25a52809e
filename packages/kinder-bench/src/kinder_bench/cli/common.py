"""What every ``kinder`` command group shares: the error exit, user-error handling, ``--import``,
``--seeds`` and ``--arg`` parsing, and commands whose options are a dataclass's fields.

This module imports no other module of :mod:`kinder_bench.cli`, so each command group imports it
and the root app (:mod:`kinder_bench.cli.kinder`) imports the groups: no import circle.
"""

from __future__ import annotations

import contextlib
import dataclasses
import inspect
import types
import typing
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, NoReturn

import typer

from kinder_bench.agents import agent_class, build_dataclass, describe_args, field_docs

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


def parse_key_values(items: list[str] | None, flag: str) -> dict[str, str]:
    """``KEY=VALUE`` items as a mapping (a later item wins); a malformed item is a user error
    naming ``flag``."""
    out: dict[str, str] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            fail(f"{flag} {item!r}: expected KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


#: Field types a generated option takes as they are (also with ``| None``, bool excepted).
_OPTION_TYPES: tuple[type, ...] = (bool, int, float, str, Path)

FieldArgOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--arg",
        help="Any argument FIELD=VALUE of the command's dataclass, parsed by the field's type "
        "(JSON for lists: keep_steps=[1000,2000]); overrides the option of that name. Repeatable.",
    ),
]
ProgressOpt = Annotated[bool, typer.Option("--progress/--no-progress", help="Show progress.")]


def _option_type(annotation: Any) -> Any | None:
    """``annotation`` when a Typer option can take it as it is (a plain type, or one ``| None``);
    None for the others (tuples, lists, mappings), which only ``--arg`` sets."""
    origin = typing.get_origin(annotation)
    if origin is typing.Union or origin is types.UnionType:
        rest = [a for a in typing.get_args(annotation) if a is not type(None)]
        plain = len(rest) == 1 and rest[0] in _OPTION_TYPES and rest[0] is not bool
        return annotation if plain else None
    return annotation if annotation in _OPTION_TYPES else None


def dataclass_command(
    app: typer.Typer,
    name: str,
    args_cls: type[Any],
    run: Callable[[Any, bool], None],
    *,
    help: str,
    what: str,
    fixed: Mapping[str, Any] | None = None,
    flags: Mapping[str, Sequence[str]] | None = None,
) -> None:
    """Add the command ``name`` to ``app`` with the dataclass ``args_cls`` as its command line
    (CleanRL's ``Args`` idea): every field is an option ``--field-name`` (``flags`` renames some)
    with the field's type and default and the docstring under the field as its help;
    ``--arg FIELD=VALUE`` sets any field, those of other types (tuples, lists) included; and
    ``--progress/--no-progress``. ``fixed`` fields are set by the command, not the user;
    ``what`` names the command in errors (``kinder train dp``).

    The command builds the dataclass with :func:`~kinder_bench.agents.build_dataclass` (the
    parsing an agent's ``--arg`` gets) and calls ``run(args, progress)``; an error the user can
    fix (a bad value, a missing file) ends it with a one-line message and status 2.
    """
    fixed = dict(fixed or {})
    flags = flags or {}
    hints = typing.get_type_hints(args_cls)
    docs = field_docs(args_cls)
    params = []
    for f in dataclasses.fields(args_cls):
        option_type = _option_type(hints[f.name])
        if f.name in fixed or not f.init or option_type is None:
            continue
        default: Any = inspect.Parameter.empty
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        option = typer.Option(*flags.get(f.name, ()), help=docs.get(f.name, ""))
        params.append(
            inspect.Parameter(
                f.name,
                inspect.Parameter.KEYWORD_ONLY,
                default=default,
                annotation=Annotated[option_type, option],
            )
        )
    for extra, annotation, default in (("arg", FieldArgOpt, None), ("progress", ProgressOpt, True)):
        params.append(
            inspect.Parameter(
                extra, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=annotation
            )
        )

    def command(**values: Any) -> None:
        progress = bool(values.pop("progress"))
        overrides = parse_key_values(values.pop("arg"), "--arg")
        for key in sorted(set(overrides) & set(fixed)):
            fail(f"--arg {key}: set by `{what}` itself ({key}={fixed[key]!r})")
        with user_errors():
            args = build_dataclass(args_cls, {**values, **overrides, **fixed}, what)
            run(args, progress)

    command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
    command.__annotations__ = {}
    command.__name__ = command.__qualname__ = f"{name}_command"
    app.command(name, help=help)(command)
