"""Agents: the interface the runner drives, the registry and argument handling.

This is the evaluation-level contract; every baseline (random and MPC included) lives in
:mod:`kinder_bench.baselines` and is registered here by its ``"module:Class"`` string, so this
package imports none of them. Agents are looked up by name (``random``, ``mpc``, ...) or by a
``"module:Class"`` entry point, so new baselines plug in without touching the runner. Arguments are
one frozen dataclass per agent (``Agent.Args``) with a docstring under every field;
:func:`make_args` builds one from a mapping (values may be strings from the command line) and
:func:`describe_args` lists the fields.
"""

from __future__ import annotations

import ast
import dataclasses
import difflib
import importlib
import inspect
import itertools
import json
import textwrap
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium

from kinder_bench.agents.base import Agent, AgentFailure, NoArgs

T = typing.TypeVar("T")

#: Agent name → ``"module:Class"``. Entry points are strings so heavy baselines import lazily.
AGENTS: dict[str, str] = {
    "random": "kinder_bench.baselines.random_agent:RandomAgent",
    "mpc": "kinder_bench.baselines.mpc:MPCAgent",
    "bilevel_planning": "kinder_bench.baselines.bilevel_planning:BilevelPlanningAgent",
    "llm_plan": "kinder_bench.baselines.fm_planning.agents:LLMPlanAgent",
    "vlm_plan": "kinder_bench.baselines.fm_planning.agents:VLMPlanAgent",
    "llm_con": "kinder_bench.baselines.fm_planning.agents:LLMConAgent",
    "vlm_con": "kinder_bench.baselines.fm_planning.agents:VLMConAgent",
    "vla": "kinder_bench.baselines.vla:VLAAgent",
    "dp": "kinder_bench.baselines.diffusion:DiffusionAgent",
    "dpes": "kinder_bench.baselines.diffusion:DPESAgent",
    "mbrl": "kinder_bench.baselines.mbrl:MBRLAgent",
    "gsc": "kinder_bench.baselines.gsc.agent:GSCAgent",
    "ppo": "kinder_bench.baselines.rl.agents:PPOAgent",
    "sac": "kinder_bench.baselines.rl.agents:SACAgent",
}


def register_agent(name: str, entry_point: str) -> None:
    """Make ``entry_point`` (``"module:Class"`` of an :class:`Agent`) available as ``name``."""
    if ":" not in entry_point:
        raise ValueError(f"entry_point must be 'module:Class', got {entry_point!r}")
    if name in AGENTS and AGENTS[name] != entry_point:
        raise ValueError(f"Agent {name!r} is already registered as {AGENTS[name]}")
    AGENTS[name] = entry_point


def agent_class(name: str) -> type[Agent[Any]]:
    """The agent class for a registered name or a ``"module:Class"`` entry point."""
    entry_point = AGENTS.get(name, name)
    if ":" not in entry_point:
        close = difflib.get_close_matches(name, list(AGENTS), n=3)
        hint = f" Did you mean {', '.join(map(repr, close))}?" if close else ""
        raise ValueError(
            f"Unknown agent {name!r}.{hint} Known agents: {', '.join(sorted(AGENTS))} (or a "
            f"'module:Class' entry point)."
        )
    module_name, _, attr = entry_point.partition(":")
    try:
        cls = getattr(importlib.import_module(module_name), attr)
    except (ImportError, AttributeError) as e:
        raise ValueError(f"Cannot load agent {name!r} from {entry_point!r}: {e}") from e
    if not (isinstance(cls, type) and issubclass(cls, Agent)):
        raise ValueError(f"Agent {name!r} ({entry_point}) is not an Agent subclass")
    return cls


def agent_name(agent: str) -> str:
    """The registered name of an agent given by name or by its ``"module:Class"`` entry point
    (an unregistered entry point is returned as it is)."""
    if agent in AGENTS:
        return agent
    return next((name for name, ep in AGENTS.items() if ep == agent), agent)


def unavailable_reason(
    name: str, env_id: str, values: Mapping[str, Any] | None = None
) -> str | None:
    """Why agent ``name`` cannot run on ``env_id`` here with arguments ``values`` (defaults
    for the rest), or None when it can: the agent's :meth:`Agent.unavailable`, or why it cannot
    even be loaded (not registered, a missing optional dependency, invalid arguments)."""
    if name not in AGENTS and ":" not in name:
        return "needs an implementation: no agent of this name is registered here"
    try:
        cls = agent_class(name)
        args = make_args(cls, values)
    except (ValueError, FileNotFoundError) as e:
        return f"needs valid arguments: {e}"
    return cls.unavailable(args, env_id)


def parse_value(raw: Any, annotation: Any, where: str) -> Any:
    """A command-line string as a value of ``annotation`` (bool, int, float, str, Path, None or
    JSON); non-strings pass through. ``where`` names the argument in the error."""
    if not isinstance(raw, str):
        return raw
    origin = typing.get_origin(annotation)
    union = origin is typing.Union or origin is types.UnionType
    options = typing.get_args(annotation) if union else (annotation,)
    if type(None) in options and raw.lower() in ("none", "null"):
        return None
    for option in options:
        if option is bool:
            if raw.lower() in ("1", "true", "yes", "on"):
                return True
            if raw.lower() in ("0", "false", "no", "off"):
                return False
        elif option in (int, float):
            try:
                return option(raw)
            except ValueError:
                continue
        elif option is str:
            return raw
        elif option is Path:
            return Path(raw)
    try:
        return json.loads(raw)
    except json.JSONDecodeError:
        raise ValueError(f"{where}: cannot parse {raw!r} as {annotation}") from None


def make_args(cls: type[Agent[Any]], values: Mapping[str, Any] | None = None) -> Any:
    """``cls.Args`` built from ``values`` (unset fields keep their defaults; strings are parsed
    by the field's type)."""
    return build_dataclass(cls.Args, values or {}, f"agent {cls.name!r}")


def build_dataclass(args_cls: type[T], values: Mapping[str, Any], what: str) -> T:
    """The dataclass ``args_cls`` built from ``values``: unset fields keep their defaults and
    strings are parsed by the field's type (:func:`parse_value`), so an agent's ``--arg`` and a
    trainer's options and ``--arg`` reach their dataclass the same way. ``what`` names the owner
    of the arguments in errors (``agent 'mpc'``, ``kinder train dp``).

    Raises:
        ValueError: naming unknown fields (and the known ones) or a value that does not parse.
    """
    fields = {f.name for f in dataclasses.fields(args_cls)}  # type: ignore[arg-type]
    unknown = sorted(set(values) - fields)
    if unknown:
        raise ValueError(
            f"Unknown argument(s) {unknown} for {what}; its arguments: {sorted(fields) or 'none'}"
        )
    hints = typing.get_type_hints(args_cls)
    parsed = {k: parse_value(v, hints[k], f"{what} argument {k!r}") for k, v in values.items()}
    return args_cls(**parsed)


def args_to_dict(args: Any) -> dict[str, Any]:
    """A dataclass of arguments as a plain (JSON-able) dict."""
    return dataclasses.asdict(args)


#: A field's ``metadata`` entry that keeps it out of the run id while it has its default value.
OMIT_DEFAULT_FROM_RUN_ID = "omit_default_from_run_id"


def run_id_optional_defaults(args_cls: Any) -> dict[str, Any]:
    """The options of an agent's ``Args`` marked ``metadata={OMIT_DEFAULT_FROM_RUN_ID: True}``,
    with their defaults: options added after runs were recorded, whose default is the behaviour
    those runs had."""
    return {
        f.name: f.default
        for f in dataclasses.fields(args_cls)
        if f.metadata.get(OMIT_DEFAULT_FROM_RUN_ID) and f.default is not dataclasses.MISSING
    }


def identity_args(args: Any) -> dict[str, Any]:
    """The arguments a run id hashes (``args``: an agent's ``Args``): every argument, except
    :func:`run_id_optional_defaults` options while they keep their default. An option added
    that way leaves the ids of runs that do not use it unchanged, so their run directories still
    resume."""
    values = args_to_dict(args)
    optional = run_id_optional_defaults(args)
    return {k: v for k, v in values.items() if k not in optional or v != optional[k]}


def field_docs(args_cls: type[Any]) -> dict[str, str]:
    """The docstrings written under each field of a dataclass (CleanRL style), inherited ones
    included."""
    docs: dict[str, str] = {}
    for base in reversed(args_cls.__mro__[1:]):
        if dataclasses.is_dataclass(base):
            docs.update(field_docs(base))
    try:
        source = textwrap.dedent(inspect.getsource(args_cls))
    except (OSError, TypeError):
        return docs
    body = ast.parse(source).body[0]
    assert isinstance(body, ast.ClassDef)
    stmts = body.body
    for stmt, nxt in itertools.pairwise(stmts):
        if (
            isinstance(stmt, ast.AnnAssign)
            and isinstance(stmt.target, ast.Name)
            and isinstance(nxt, ast.Expr)
            and isinstance(nxt.value, ast.Constant)
            and isinstance(nxt.value.value, str)
        ):
            docs[stmt.target.id] = " ".join(nxt.value.value.split())
    return docs


def describe_args(cls: type[Agent[Any]]) -> list[tuple[str, str, Any, str]]:
    """``(name, type, default, docstring)`` for each argument of an agent."""
    docs = field_docs(cls.Args)
    hints = typing.get_type_hints(cls.Args)
    out = []
    for f in dataclasses.fields(cls.Args):
        type_name = getattr(hints[f.name], "__name__", str(hints[f.name]))
        out.append((f.name, type_name, f.default, docs.get(f.name, "")))
    return out


def make_agent(
    name: str,
    env: gymnasium.Env[Any, Any],
    args: Mapping[str, Any] | Any | None = None,
    seed: int = 0,
) -> Agent[Any]:
    """An agent by name, with arguments given as a mapping or as its ``Args`` dataclass."""
    cls = agent_class(name)
    if args is None or isinstance(args, Mapping):
        args = make_args(cls, args)
    return cls(env, args, seed)


__all__ = [
    "AGENTS",
    "OMIT_DEFAULT_FROM_RUN_ID",
    "Agent",
    "AgentFailure",
    "NoArgs",
    "agent_class",
    "agent_name",
    "args_to_dict",
    "describe_args",
    "field_docs",
    "identity_args",
    "make_agent",
    "make_args",
    "register_agent",
    "run_id_optional_defaults",
    "unavailable_reason",
]
