"""Import (and export) the upstream KinDER demonstration formats.

Two formats exist upstream (KinDER baselines spec §3.4 and §4):

* **The episode pickle** (one file per episode, written with ``dill``; path
  ``<dir>/<Env-variant>/<seed>/<timestamp>.p``): a dict with ``env_id``, ``timestamp``, ``seed``,
  ``observations`` (``T + 1`` flat vectors), ``actions`` (``T``), ``rewards``, ``terminated``,
  ``truncated`` and, for skill-labelled demos, ``skill_info``: one dict per executed skill with
  ``operator_name``, ``operator_objects`` (``(name, type)`` pairs), ``controller_class``,
  ``controller_objects``, ``params`` and ``num_actions``. :func:`load_upstream_pickle` turns it
  into an :class:`EpisodeRecord` (source ``imported``; the skill steps are the running sums of
  ``num_actions``; the controller fields go to ``metadata``).
* **The robomimic-style HDF5** made from the pickles for training: groups ``data/demo_<i>`` with
  ``obs/robot_state``, ``obs/env_state``, ``obs/<camera>`` images and ``actions``, attribute
  ``num_frames``. It has no seed, rewards or final observation. :func:`load_upstream_hdf5` joins
  the two state parts **by name** into this env's Box layout (:class:`StateSplit`), assumes the
  upstream parts list the same features in the same order (their widths are checked), and
  completes each episode with this env's model: the final observation is ``transition(last
  observation, last action)``, rewards and ``terminated`` come from the same model steps. The
  seed is unknown (``-1``), so such records cannot be replayed from a seed; they carry their
  states (= observations) instead, which is what the images are rendered from.
  :func:`write_upstream_hdf5` exports records in the same layout (plus ``seed``, ``terminated``
  and the full ``states`` for a lossless round trip; images are not exported).

Caveats, stated plainly: this is a clean-room re-implementation, so an upstream observation is
only meaningful here when the env's feature layout matches upstream's (same objects, features and
order). The importers check the widths; they cannot check the semantics. Pickles can run code
when loaded: only import files you trust.
"""

from __future__ import annotations

import pickle
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kinder_gym.demos.layout import StateSplit
from kinder_gym.demos.record import EpisodeRecord, SkillLabel


class UpstreamFormatError(ValueError):
    """An upstream demo file is unreadable or lacks what the format promises (names the file)."""


def _load_pickle(path: Path) -> Any:
    try:
        import dill

        loader: Any = dill
    except ImportError:  # dill pickles of plain data load with pickle too
        loader = pickle
    try:
        with open(path, "rb") as f:
            return loader.load(f)
    except FileNotFoundError:
        raise UpstreamFormatError(f"{path}: no such file") from None
    except Exception as e:  # truncated or not a pickle: EOFError, UnpicklingError, ...
        raise UpstreamFormatError(
            f"{path}: not a readable demo pickle ({type(e).__name__}: {e}); it is truncated or "
            f"corrupt"
        ) from None


def record_from_upstream_dict(data: Mapping[str, Any], where: str = "<dict>") -> EpisodeRecord:
    """An :class:`EpisodeRecord` from an upstream episode dict (module docstring)."""
    missing = [
        k
        for k in ("env_id", "seed", "observations", "actions", "rewards", "terminated")
        if k not in data
    ]
    if missing:
        raise UpstreamFormatError(
            f"{where}: not an upstream KinDER demo: missing key(s) {missing} (found {sorted(data)})"
        )
    observations = np.asarray(np.stack(list(data["observations"])), dtype=np.float64)
    actions_list = list(data["actions"])
    actions = (
        np.asarray(np.stack(actions_list), dtype=np.float64) if actions_list else np.zeros((0, 0))
    )
    skills: list[SkillLabel] = []
    controllers: list[dict[str, Any]] = []
    start = 0
    for info in data.get("skill_info") or []:
        n = int(info["num_actions"])
        objects = [
            o[0] if isinstance(o, (tuple, list)) else str(o) for o in info["operator_objects"]
        ]
        params = np.asarray(info.get("params", ()), dtype=np.float64).ravel()
        skills.append(
            SkillLabel(
                operator=str(info["operator_name"]),
                objects=tuple(str(o) for o in objects),
                params=tuple(float(p) for p in params),
                start=start,
                end=start + n,
            )
        )
        controllers.append(
            {
                "controller_class": str(info.get("controller_class", "")),
                "controller_objects": [
                    o[0] if isinstance(o, (tuple, list)) else str(o)
                    for o in info.get("controller_objects", [])
                ],
            }
        )
        start += n
    try:
        return EpisodeRecord(
            env_id=str(data["env_id"]),
            seed=int(data["seed"]),
            source="imported",
            observations=observations,
            actions=actions,
            rewards=np.asarray(data["rewards"], dtype=np.float64),
            terminated=bool(data["terminated"]),
            truncated=bool(data.get("truncated", False)),
            states=None,
            skills=skills,
            versions={},
            metadata={
                "imported_from": where,
                "format": "upstream-pickle",
                "timestamp": int(data.get("timestamp", 0)),
                "controllers": controllers,
            },
        )
    except ValueError as e:
        raise UpstreamFormatError(f"{where}: inconsistent demo ({e})") from None


def load_upstream_pickle(path: Path | str) -> EpisodeRecord:
    """One upstream episode pickle as an :class:`EpisodeRecord`."""
    path = Path(path)
    data = _load_pickle(path)
    if not isinstance(data, Mapping):
        raise UpstreamFormatError(
            f"{path}: expected a dict (an upstream demo), got {type(data).__name__}"
        )
    return record_from_upstream_dict(data, str(path))


def find_upstream_pickles(root: Path | str) -> list[Path]:
    """Every ``*.p`` / ``*.pkl`` file under ``root`` (or ``root`` itself), sorted."""
    root = Path(root)
    if root.is_file():
        return [root]
    return sorted(p for p in root.rglob("*") if p.suffix in (".p", ".pkl") and p.is_file())


def _open_h5(path: Path, mode: str) -> Any:
    try:
        import h5py
    except ImportError as e:
        raise ImportError("HDF5 import needs h5py: `pip install 'kinder-gym[demos]'`") from e
    try:
        return h5py.File(path, mode)
    except FileNotFoundError:
        raise UpstreamFormatError(f"{path}: no such file") from None
    except OSError as e:
        raise UpstreamFormatError(
            f"{path}: not a readable HDF5 file ({e}); it is truncated or corrupt"
        ) from None


def load_upstream_hdf5(path: Path | str, env_id: str) -> list[EpisodeRecord]:
    """Every ``data/demo_<i>`` of an upstream robomimic-style HDF5 as :class:`EpisodeRecord` s of
    ``env_id`` (module docstring: how the missing parts are completed)."""
    import kinder_core

    path = Path(path)
    env = kinder_core.make(env_id)
    model = env.unwrapped
    split = StateSplit.from_env(env)
    records = []
    with _open_h5(path, "r") as f:
        if "data" not in f:
            raise UpstreamFormatError(f"{path}: no 'data' group; not a robomimic-style demo file")
        names = sorted(f["data"].keys(), key=_demo_number)
        for name in names:
            group = f["data"][name]
            where = f"{path}:data/{name}"
            try:
                robot = np.asarray(group["obs"]["robot_state"], dtype=np.float64)
                rest = np.asarray(group["obs"]["env_state"], dtype=np.float64)
                actions = np.asarray(group["actions"], dtype=np.float64)
            except KeyError as e:
                raise UpstreamFormatError(f"{where}: missing {e}") from None
            try:
                obs = split.join(robot, rest)
            except ValueError as e:
                raise UpstreamFormatError(f"{where}: does not fit {env_id}'s layout: {e}") from None
            if "states" in group:  # written by write_upstream_hdf5: lossless
                states = np.asarray(group["states"], dtype=np.float64)
                obs_full = states if len(states) == len(actions) + 1 else None
            else:
                obs_full = None
            if obs_full is None:
                if len(obs) != len(actions):
                    raise UpstreamFormatError(
                        f"{where}: {len(obs)} observations for {len(actions)} actions; expected "
                        f"one observation per action"
                    )
                obs_full, rewards, terminated = _complete(model, obs, actions)
            else:
                _, rewards, terminated = _complete(model, obs_full[:-1], actions)
            seed = int(group.attrs.get("seed", -1))
            records.append(
                EpisodeRecord(
                    env_id=env_id,
                    seed=seed,
                    source="imported",
                    observations=obs_full,
                    actions=actions,
                    rewards=rewards,
                    terminated=bool(group.attrs.get("terminated", terminated)),
                    truncated=False,
                    states=obs_full.copy(),
                    versions={},
                    metadata={"imported_from": where, "format": "upstream-hdf5"},
                )
            )
    return records


def _demo_number(name: str) -> tuple[int, str]:
    tail = name.rsplit("_", 1)[-1]
    return (int(tail), name) if tail.isdigit() else (1 << 62, name)


def _complete(
    model: Any, obs: np.ndarray[Any, Any], actions: np.ndarray[Any, Any]
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any], bool]:
    """Observations with the final one added, rewards and termination from the env's model."""
    rewards = []
    terminated = False
    next_state = None
    for x, a in zip(obs, actions):
        next_state, reward, terminated = model.transition(x, a)
        rewards.append(reward)
    if next_state is None:
        return obs, np.zeros(0), False
    final = model.box_space.vectorize(next_state).astype(np.float64)
    return np.vstack([obs, final[None]]), np.asarray(rewards, dtype=np.float64), bool(terminated)


def write_upstream_hdf5(
    path: Path | str, records: Sequence[EpisodeRecord], split: StateSplit
) -> Path:
    """Export ``records`` as a robomimic-style HDF5 (``data/demo_<i>/obs/{robot_state,
    env_state}``, ``actions``; attributes ``num_frames``, ``seed``, ``terminated``; plus the full
    ``states`` (``T + 1`` rows) so that :func:`load_upstream_hdf5` is lossless). Written to a
    temporary file and renamed."""
    import os

    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with _open_h5(tmp, "w") as f:
        data = f.create_group("data")
        total = 0
        for i, record in enumerate(records):
            group = data.create_group(f"demo_{i}")
            robot, rest = split.split(record.observations[:-1])
            obs = group.create_group("obs")
            obs.create_dataset("robot_state", data=robot)
            obs.create_dataset("env_state", data=rest)
            group.create_dataset("actions", data=record.actions)
            states = record.states if record.states is not None else record.observations
            group.create_dataset("states", data=states)
            group.attrs["num_frames"] = record.num_steps
            group.attrs["seed"] = int(record.seed)
            group.attrs["terminated"] = bool(record.terminated)
            total += record.num_steps
        f.attrs["total_episodes"] = len(records)
        f.attrs["total_frames"] = total
        f.attrs["env_id"] = records[0].env_id if records else ""
    os.replace(tmp, path)
    return path


__all__ = [
    "UpstreamFormatError",
    "find_upstream_pickles",
    "load_upstream_hdf5",
    "load_upstream_pickle",
    "record_from_upstream_dict",
    "write_upstream_hdf5",
]
