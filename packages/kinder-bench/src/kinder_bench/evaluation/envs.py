"""Looking up and making KinDER environments, with helpful errors for unknown ids."""

from __future__ import annotations

import difflib
import re
from typing import Any

import gymnasium

import kinder_core
from kinder_core.registration import NAMESPACE, ensure_registered


class UnknownEnvError(ValueError):
    """An environment id that no installed package registers."""


def known_env_ids() -> list[str]:
    """Every registered KinDER id: the installed garden packages' ids, then any other
    ``kinder/...`` id registered with gymnasium in this process (e.g. by ``--import``)."""
    ids = kinder_core.list_envs()
    extra = sorted(i for i in gymnasium.registry if i.startswith(f"{NAMESPACE}/") and i not in ids)
    return ids + extra


def short_id(env_id: str) -> str:
    """``kinder/Motion2D-p0-v0`` → ``Motion2D-p0`` (for tables and file names)."""
    s = env_id.removeprefix(f"{NAMESPACE}/")
    return re.sub(r"-v\d+$", "", s)


def _candidates(env_id: str) -> list[str]:
    out = [env_id]
    if not env_id.startswith(f"{NAMESPACE}/"):
        out.append(f"{NAMESPACE}/{env_id}")
    out += [c + "-v0" for c in list(out) if not re.search(r"-v\d+$", c)]
    return out


def resolve_env_id(env_id: str) -> str:
    """The full registered id for ``env_id``, which may omit the ``kinder/`` namespace and the
    ``-v0`` version (``Motion2D-p0``). Imports the providing package on demand.

    Raises:
        UnknownEnvError: with the closest known ids, when nothing matches.
        ModuleNotFoundError: when the providing package is not installed (says what to install).
    """
    for candidate in _candidates(env_id):
        try:
            ensure_registered(candidate)
        except (ValueError, gymnasium.error.Error):
            continue
        return candidate
    known = known_env_ids()
    by_short = {short_id(i).lower(): i for i in known}
    close = difflib.get_close_matches(short_id(env_id).lower(), list(by_short), n=3, cutoff=0.5)
    hint = f" Did you mean {', '.join(by_short[c] for c in close)}?" if close else ""
    listing = (
        " Run `kinder envs` to list them." if known else " No KinDER environment is installed."
    )
    raise UnknownEnvError(f"Unknown environment {env_id!r}.{hint}{listing}")


def default_max_steps(env_id: str) -> int:
    """The registered step budget of an id (gymnasium's ``max_episode_steps``)."""
    spec = gymnasium.spec(env_id)
    if spec.max_episode_steps is None:
        raise ValueError(f"{env_id} has no max_episode_steps; give max_steps explicitly")
    return int(spec.max_episode_steps)


def make_env(env_id: str, max_steps: int | None = None, **kwargs: Any) -> gymnasium.Env[Any, Any]:
    """A registered id's Box view, with the step budget replaced by ``max_steps`` when given."""
    if max_steps is not None:
        kwargs["max_episode_steps"] = max_steps
    return kinder_core.make(env_id, **kwargs)
