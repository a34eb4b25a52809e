"""Demonstration datasets as LeRobotDataset v3 (lerobot 0.4.4): writing, checking and reading.

One dataset holds the demonstrations of one env. It is a standard LeRobotDataset v3 directory
(``meta/info.json``, ``meta/stats.json``, ``meta/tasks.parquet``, ``meta/episodes/...``,
``data/chunk-*/file-*.parquet``, ``videos/<key>/chunk-*/file-*.mp4``) written and read with
lerobot's own ``LeRobotDataset``, plus two KinDER files under ``meta/`` that lerobot ignores.

**Per-frame features.** Episode of ``T`` steps → ``T`` frames; frame ``t`` is the observation
before action ``t`` and that action's outcome.

============================== ============== ================================================
key                            dtype (shape)  content
============================== ============== ================================================
``observation.state``          float32 (S,)   the robot object's features (names ``robot.x``…)
``observation.environment_...`` float32 (E,)  every other feature (names ``block0.x``…)
``observation.images.<cam>``   video (H,W,3)  2D: ``render``; 3D: ``base``, ``wrist``,
                                              ``overview``; 224×224 (:mod:`.layout`)
``action``                     float32 (A,)   the action applied (after clipping)
``next.reward``                float32 (1,)   the step's reward
``next.done``                  bool (1,)      terminated or truncated after this step
``next.truncated``             bool (1,)      truncated (time limit) after this step
``episode_seed``               int64 (1,)     the reset seed (repeated on every frame)
``skill_index``                int64 (1,)     which of the episode's skill labels produced the
                                              step (−1: none)
``subtask_index``              int64 (1,)     the skill's operator name as an index into
                                              ``meta/subtasks.parquet`` (0: ``"none"``);
                                              lerobot's loader adds ``item["subtask"]``
``kinder.observation``         float64 (D,)   the full Box observation
``kinder.state``               float64 (D,)   the full object-centric state vector
``kinder.action``              float64 (A,)   the applied action, unrounded (exact replay)
``kinder.reward``              float64 (1,)   the reward, unrounded
``kinder.step_seconds``        float64 (1,)   wall-clock seconds of the step (NaN: unknown)
``task``                       string         the env's natural-language goal
============================== ============== ================================================

The float32 policy features are views of the float64 ``kinder.*`` columns, which keep replay exact
(a float32 action does not reproduce a trajectory to 1e-9). ``kinder.*`` and the indices are
not prefixed ``observation.``, so lerobot's policies ignore them.

**The KinDER sidecar** (lerobot has no API for extra per-episode columns, so they go in files it
ignores): ``meta/kinder.json`` (format version, env id, fps, cameras, image size, the
:class:`~kinder_gym.demos.layout.StateSplit` of feature names and robot objects, the action
names) and ``meta/kinder_episodes.jsonl``, one JSON line per episode in episode order: seed,
source, terminated/truncated, skill labels, package versions, task, free-form metadata, and the
final observation and state (frame rows hold the ``T`` pre-step rows; the ``T + 1``-th lives
here). JSON floats round-trip exactly.

**Images** are rendered from the recorded states (:func:`~kinder_gym.demos.layout.camera_frames`
on a separate render env), so collection never renders; a record without states is replayed
from its seed first. Videos are encoded with lerobot's default codec (AV1, ``libsvtav1``) unless
``vcodec`` says otherwise, one encoder thread, cameras one after another (this machine is small).

**Resuming and crashes.** Opening an existing dataset appends to it (lerobot starts a new parquet
file). A dataset is valid only after :meth:`DemoWriter.close` (lerobot writes parquet footers
then); a process killed mid-write leaves it unreadable (:func:`check_dataset` names the file).
The collectors therefore keep every episode as an atomic per-episode file first and build the
dataset from those in one pass (:mod:`kinder_gym.demos.store`).

Nothing here touches the network: ``HF_HUB_OFFLINE=1`` is set before lerobot is imported.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinder_gym.demos.layout import (
    IMAGE_SIZE,
    StateSplit,
    camera_frames,
    camera_names,
    image_env_kwargs,
    set_render_size,
)
from kinder_gym.demos.record import EpisodeRecord, SkillLabel

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("SVT_LOG", "1")  # the AV1 encoder's banner: errors only

FORMAT_VERSION = 1
KINDER_META = "meta/kinder.json"
EPISODES_META = "meta/kinder_episodes.jsonl"
SUBTASKS_META = "meta/subtasks.parquet"
NO_SKILL = "none"
#: Frames per second recorded in the dataset (the envs' ``render_fps``).
DEFAULT_FPS = 20


class DatasetError(ValueError):
    """A dataset file is missing, truncated or inconsistent (the message names the file)."""


def _short(env_id: str) -> str:
    s = env_id.removeprefix("kinder/")
    return s[: -len("-v0")] if s.endswith("-v0") else s


def repo_id_for(env_id: str) -> str:
    """The dataset's (local-only) lerobot repo id, e.g. ``kinder/Motion2D-p0``."""
    return f"kinder/{_short(env_id)}"


def image_key(camera: str) -> str:
    return f"observation.images.{camera}"


def dataset_features(
    split: StateSplit,
    action_dim: int,
    cameras: Sequence[str],
    image_size: int = IMAGE_SIZE,
) -> dict[str, dict[str, Any]]:
    """The lerobot feature spec of a KinDER dataset (module docstring)."""
    names = list(split.feature_names)
    action_names = [f"action{i}" for i in range(action_dim)]
    features: dict[str, dict[str, Any]] = {
        "observation.state": {
            "dtype": "float32",
            "shape": (len(split.state_names),),
            "names": split.state_names,
        },
        "observation.environment_state": {
            "dtype": "float32",
            "shape": (len(split.env_names),),
            "names": split.env_names,
        },
        "action": {"dtype": "float32", "shape": (action_dim,), "names": action_names},
        "next.reward": {"dtype": "float32", "shape": (1,), "names": None},
        "next.done": {"dtype": "bool", "shape": (1,), "names": None},
        "next.truncated": {"dtype": "bool", "shape": (1,), "names": None},
        "episode_seed": {"dtype": "int64", "shape": (1,), "names": None},
        "skill_index": {"dtype": "int64", "shape": (1,), "names": None},
        "subtask_index": {"dtype": "int64", "shape": (1,), "names": None},
        "kinder.observation": {"dtype": "float64", "shape": (len(names),), "names": names},
        "kinder.state": {"dtype": "float64", "shape": (len(names),), "names": names},
        "kinder.action": {"dtype": "float64", "shape": (action_dim,), "names": action_names},
        "kinder.reward": {"dtype": "float64", "shape": (1,), "names": None},
        "kinder.step_seconds": {"dtype": "float64", "shape": (1,), "names": None},
    }
    for cam in cameras:
        features[image_key(cam)] = {
            "dtype": "video",
            "shape": (image_size, image_size, 3),
            "names": ["height", "width", "channels"],
        }
    return features


def _write_text_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _episode_meta(record: EpisodeRecord, index: int) -> dict[str, Any]:
    return {
        "episode_index": index,
        "env_id": record.env_id,
        "seed": int(record.seed),
        "source": record.source,
        "num_steps": record.num_steps,
        "terminated": bool(record.terminated),
        "truncated": bool(record.truncated),
        "task": record.task,
        "skills": [s.to_dict() for s in record.skills],
        "versions": dict(record.versions),
        "metadata": record.metadata,
        "has_step_seconds": record.step_seconds is not None,
        "final_observation": [float(v) for v in record.observations[-1]],
        "final_state": None if record.states is None else [float(v) for v in record.states[-1]],
    }


def env_task(env: Any) -> str:
    """The env's natural-language goal: its documentation summary on one line."""
    summary = str(env.unwrapped.metadata.get("summary", ""))
    return " ".join(summary.split())


class DemoWriter:
    """Writes :class:`EpisodeRecord` s of one env into a LeRobotDataset v3 at ``root``.

    Use as a context manager (or call :meth:`close`): ``with DemoWriter(root, env_id) as w:
    w.add(record)``. Reopening an existing dataset appends to it; its env, cameras and image
    size must match.

    Args:
        root: The dataset directory (created; must be empty or an existing KinDER dataset).
        env_id: The registered id of the env every record comes from.
        images: Render camera images from the recorded states (module docstring).
        image_size: Pixels per side of every image.
        fps: The frame rate written to ``info.json``.
        vcodec: lerobot's video codec (``libsvtav1``, ``h264``, ...).
        robot_objects: Override the robot objects of the state split (default: by type name).
    """

    def __init__(
        self,
        root: Path | str,
        env_id: str,
        *,
        images: bool = True,
        image_size: int = IMAGE_SIZE,
        fps: int = DEFAULT_FPS,
        vcodec: str = "libsvtav1",
        robot_objects: Sequence[str] | None = None,
    ) -> None:
        import kinder_core

        self.root = Path(root)
        self.env_id = env_id
        self.images = images
        self.image_size = image_size
        kwargs = image_env_kwargs(env_id, image_size) if images else {}
        self.env = kinder_core.make(env_id, render_mode="rgb_array", **kwargs)
        if images:
            set_render_size(self.env, image_size)
        self.split = StateSplit.from_env(self.env, robot_objects)
        self.action_dim = int(self.env.action_space.shape[0])  # type: ignore[index]
        self.cameras = camera_names(self.env) if images else ()
        self.task = env_task(self.env)
        self._fps = fps
        self._closed = False
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        info = self.root / "meta" / "info.json"
        if info.exists():
            meta = read_kinder_meta(self.root)
            expected = self._kinder_meta()
            for key in ("env_id", "cameras", "image_size", "split", "fps"):
                if meta.get(key) != expected[key]:
                    raise DatasetError(
                        f"{self.root / KINDER_META}: the dataset has {key}={meta.get(key)!r}, but "
                        f"this writer has {expected[key]!r}; write to a new directory"
                    )
            check_dataset(self.root)
            self.dataset = LeRobotDataset(
                repo_id_for(env_id), root=self.root, vcodec=vcodec, encoder_threads=1
            )
            self._episodes = _read_episode_lines(self.root)
            self._subtasks = _read_subtasks(self.root)
        else:
            if self.root.exists() and any(self.root.iterdir()):
                raise DatasetError(
                    f"{self.root}: exists and is not a dataset (no meta/info.json); expected an "
                    f"empty or missing directory, or an existing KinDER dataset to append to"
                )
            if self.root.exists():
                self.root.rmdir()  # lerobot creates it (mkdir exist_ok=False)
            self.dataset = LeRobotDataset.create(
                repo_id=repo_id_for(env_id),
                fps=fps,
                features=dataset_features(self.split, self.action_dim, self.cameras, image_size),
                root=self.root,
                robot_type=None,
                use_videos=bool(self.cameras),
                vcodec=vcodec,
                encoder_threads=1,
            )
            _write_text_atomic(self.root / KINDER_META, json.dumps(self._kinder_meta(), indent=2))
            self._episodes = []
            self._subtasks = [NO_SKILL]

    def _kinder_meta(self) -> dict[str, Any]:
        return {
            "format_version": FORMAT_VERSION,
            "env_id": self.env_id,
            "fps": self._fps,
            "cameras": list(self.cameras),
            "image_size": self.image_size,
            "split": self.split.to_dict(),
            "action_dim": self.action_dim,
            "task": self.task,
        }

    @property
    def num_episodes(self) -> int:
        return len(self._episodes)

    def _states_of(self, record: EpisodeRecord) -> NDArray[np.float64]:
        if record.states is not None:
            return record.states
        if record.seed < 0:
            raise ValueError(
                f"Record of {record.env_id} has neither states nor a known seed (seed "
                f"{record.seed}), so its states cannot be recovered by replay; give it states"
            )
        from kinder_gym.demos.replay import replay_states

        return replay_states(self.env, record)

    def add(self, record: EpisodeRecord) -> None:
        """Append one episode (rendering its images when the writer has cameras)."""
        if self._closed:
            raise RuntimeError(f"DemoWriter({self.root}) is closed")
        if record.env_id != self.env_id:
            raise ValueError(
                f"Record of {record.env_id} (seed {record.seed}) cannot go into the dataset of "
                f"{self.env_id} at {self.root}"
            )
        dim = self.split.dim
        if record.observations.shape[1] != dim or record.actions.shape[1:] != (self.action_dim,):
            raise ValueError(
                f"Record {record.env_id} seed {record.seed}: observations of width "
                f"{record.observations.shape[1]} and actions {record.actions.shape[1:]}; expected "
                f"{dim} and ({self.action_dim},)"
            )
        if record.num_steps == 0:
            raise ValueError(
                f"Record {record.env_id} seed {record.seed} has no steps; LeRobot episodes need "
                f"at least one frame"
            )
        states = self._states_of(record)
        if record.states is None:
            record = _with_states(record, states)
        skill_of_step = np.full(record.num_steps, -1, dtype=np.int64)
        subtask_of_step = np.zeros(record.num_steps, dtype=np.int64)
        for i, label in enumerate(record.skills):
            if label.operator not in self._subtasks:
                self._subtasks.append(label.operator)
            skill_of_step[label.start : label.end] = i
            subtask_of_step[label.start : label.end] = self._subtasks.index(label.operator)
        obs_state, obs_env = self.split.split(record.observations)
        seconds = (
            record.step_seconds
            if record.step_seconds is not None
            else np.full(record.num_steps, np.nan)
        )
        task = record.task or self.task
        last = record.num_steps - 1
        for t in range(record.num_steps):
            done = t == last and (record.terminated or record.truncated)
            frame: dict[str, Any] = {
                "observation.state": obs_state[t].astype(np.float32),
                "observation.environment_state": obs_env[t].astype(np.float32),
                "action": record.actions[t].astype(np.float32),
                "next.reward": np.array([record.rewards[t]], dtype=np.float32),
                "next.done": np.array([done], dtype=bool),
                "next.truncated": np.array([t == last and record.truncated], dtype=bool),
                "episode_seed": np.array([record.seed], dtype=np.int64),
                "skill_index": skill_of_step[t : t + 1],
                "subtask_index": subtask_of_step[t : t + 1],
                "kinder.observation": record.observations[t],
                "kinder.state": states[t],
                "kinder.action": record.actions[t],
                "kinder.reward": np.array([record.rewards[t]], dtype=np.float64),
                "kinder.step_seconds": np.array([seconds[t]], dtype=np.float64),
                "task": task,
            }
            if self.cameras:
                for cam, img in camera_frames(self.env, states[t], self.image_size).items():
                    frame[image_key(cam)] = img
            self.dataset.add_frame(frame)
        _squeeze_scalar_columns(self.dataset)
        self.dataset.save_episode(parallel_encoding=False)
        line = _episode_meta(record, len(self._episodes))
        line["task"] = task
        self._episodes.append(line)
        with open(self.root / EPISODES_META, "a") as f:
            f.write(json.dumps(line, sort_keys=True) + "\n")
            f.flush()
            os.fsync(f.fileno())

    def close(self) -> None:
        """Finalise the dataset (parquet footers, metadata); safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self.dataset.finalize()
        _write_subtasks(self.root, self._subtasks)
        self.env.close()

    def __enter__(self) -> DemoWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _squeeze_scalar_columns(dataset: Any) -> None:
    """Turn the buffered ``(1,)`` values into 0-d arrays before ``save_episode``.

    lerobot 0.4.4 validates a ``(1,)`` feature as a ``(1,)`` array in ``add_frame`` but stores it
    as a scalar column, converting each row with ``float(row)``, which numpy >= 2.4 refuses for a
    1-element 1-d array. 0-d rows stack to ``(T,)``, the layout its statistics code expects."""
    buffer = dataset.episode_buffer
    for key, feature in dataset.features.items():
        scalar = tuple(feature["shape"]) == (1,) and feature["dtype"] not in ("video", "string")
        if scalar and isinstance(buffer.get(key), list):
            buffer[key] = [np.asarray(v).reshape(()) for v in buffer[key]]


def _with_states(record: EpisodeRecord, states: NDArray[np.float64]) -> EpisodeRecord:
    import dataclasses

    return dataclasses.replace(record, states=states)


def _write_subtasks(root: Path, subtasks: Sequence[str]) -> None:
    import pandas as pd

    frame = pd.DataFrame({"subtask_index": range(len(subtasks))}, index=list(subtasks))
    path = root / SUBTASKS_META
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    frame.to_parquet(tmp)
    os.replace(tmp, path)


def _read_subtasks(root: Path) -> list[str]:
    path = root / SUBTASKS_META
    if not path.exists():
        return [NO_SKILL]
    import pandas as pd

    try:
        frame = pd.read_parquet(path)
    except Exception as e:
        raise DatasetError(f"{path}: cannot read ({type(e).__name__}: {e})") from None
    return [str(i) for i in frame.sort_values("subtask_index").index]


def read_kinder_meta(root: Path | str) -> dict[str, Any]:
    """``meta/kinder.json`` of a dataset."""
    path = Path(root) / KINDER_META
    if not path.exists():
        raise DatasetError(f"{path}: missing; {root} is not a KinDER demonstration dataset")
    try:
        meta: dict[str, Any] = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DatasetError(f"{path}: not valid JSON ({e})") from None
    if meta.get("format_version") != FORMAT_VERSION:
        raise DatasetError(
            f"{path}: format_version {meta.get('format_version')!r}; this reader expects "
            f"{FORMAT_VERSION}"
        )
    return meta


def _read_episode_lines(root: Path) -> list[dict[str, Any]]:
    path = root / EPISODES_META
    if not path.exists():
        return []
    out = []
    for n, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError as e:
            raise DatasetError(f"{path}:{n}: not a JSON line ({e}); the file is corrupt") from None
    return out


def check_dataset(root: Path | str) -> None:
    """Check that every file of a dataset is there and readable; raise :class:`DatasetError`
    naming the first bad file (truncated parquet, broken JSON, missing video, count mismatch)."""
    import pyarrow.parquet as pq

    root = Path(root)
    read_kinder_meta(root)
    info_path = root / "meta" / "info.json"
    try:
        info = json.loads(info_path.read_text())
    except FileNotFoundError:
        raise DatasetError(f"{info_path}: missing") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DatasetError(f"{info_path}: not valid JSON ({e})") from None
    parquet = sorted((root / "data").glob("*/*.parquet")) + sorted(
        (root / "meta" / "episodes").glob("*/*.parquet")
    )
    if (root / "meta" / "tasks.parquet").exists():
        parquet.append(root / "meta" / "tasks.parquet")
    rows = {"data": 0, "episodes": 0}
    for path in parquet:
        try:
            n = pq.read_metadata(path).num_rows
        except Exception as e:
            raise DatasetError(
                f"{path}: not a readable parquet file ({type(e).__name__}: {e}); it is truncated "
                f"or corrupt (was the writer closed?)"
            ) from None
        if path.parts[-3] == "data":
            rows["data"] += n
        elif path.parts[-4:-2] == ("meta", "episodes"):
            rows["episodes"] += n
    if rows["data"] != info.get("total_frames") or rows["episodes"] != info.get("total_episodes"):
        raise DatasetError(
            f"{info_path}: says {info.get('total_episodes')} episodes / {info.get('total_frames')} "
            f"frames, but the parquet files hold {rows['episodes']} / {rows['data']}"
        )
    episodes = _read_episode_lines(root)
    if len(episodes) != rows["episodes"]:
        raise DatasetError(
            f"{root / EPISODES_META}: has {len(episodes)} episode lines, but the dataset has "
            f"{rows['episodes']} episodes"
        )
    for key, feature in info.get("features", {}).items():
        if feature.get("dtype") != "video":
            continue
        videos = sorted((root / "videos" / key).glob("*/*.mp4"))
        if rows["episodes"] and not videos:
            raise DatasetError(f"{root / 'videos' / key}: no video files for camera {key}")
        for video in videos:
            if video.stat().st_size == 0:
                raise DatasetError(f"{video}: empty video file")


def load_dataset(root: Path | str, **kwargs: Any) -> Any:
    """The dataset as a ``lerobot`` ``LeRobotDataset`` (for training code), after
    :func:`check_dataset`. ``kwargs`` go to ``LeRobotDataset`` (``delta_timestamps``,
    ``episodes``, ...)."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = Path(root)
    check_dataset(root)
    meta = read_kinder_meta(root)
    return LeRobotDataset(repo_id_for(meta["env_id"]), root=root, **kwargs)


def _column(table: Any, key: str, width: int) -> NDArray[Any]:
    col = table.column(key).combine_chunks()
    if hasattr(col, "flatten"):  # a fixed-size list column; scalar columns are stored as values
        col = col.flatten()
    flat = col.to_numpy(zero_copy_only=False)
    return np.asarray(flat).reshape(-1, width)


def load_records(root: Path | str, episodes: Iterable[int] | None = None) -> list[EpisodeRecord]:
    """The dataset's episodes as :class:`EpisodeRecord` s, read through lerobot (images are not
    read; render them from the states with :func:`~kinder_gym.demos.layout.camera_frames`)."""
    ds = load_dataset(root)
    meta = read_kinder_meta(root)
    lines = _read_episode_lines(Path(root))
    dim = len(meta["split"]["feature_names"])
    act = int(meta["action_dim"])
    table = ds.hf_dataset.with_format("arrow")[:]
    ep_index = table.column("episode_index").to_numpy()
    frame_index = table.column("frame_index").to_numpy()
    cols = {
        "obs": _column(table, "kinder.observation", dim),
        "state": _column(table, "kinder.state", dim),
        "action": _column(table, "kinder.action", act),
        "reward": _column(table, "kinder.reward", 1)[:, 0],
        "seconds": _column(table, "kinder.step_seconds", 1)[:, 0],
    }
    wanted = range(len(lines)) if episodes is None else list(episodes)
    records = []
    for i in wanted:
        if not 0 <= i < len(lines):
            raise IndexError(f"{root}: episode {i} out of range (0..{len(lines) - 1})")
        line = lines[i]
        rows = np.flatnonzero(ep_index == i)
        rows = rows[np.argsort(frame_index[rows])]
        if len(rows) != line["num_steps"]:
            raise DatasetError(
                f"{Path(root) / EPISODES_META}: episode {i} should have {line['num_steps']} "
                f"frames, the data files have {len(rows)}"
            )
        final_state = line["final_state"]
        states = None
        if final_state is not None:
            states = np.vstack([cols["state"][rows], np.asarray(final_state)[None]])
        records.append(
            EpisodeRecord(
                env_id=line["env_id"],
                seed=int(line["seed"]),
                source=line["source"],
                observations=np.vstack(
                    [cols["obs"][rows], np.asarray(line["final_observation"])[None]]
                ),
                actions=cols["action"][rows],
                rewards=cols["reward"][rows],
                terminated=bool(line["terminated"]),
                truncated=bool(line["truncated"]),
                states=states,
                step_seconds=cols["seconds"][rows] if line["has_step_seconds"] else None,
                skills=[SkillLabel.from_dict(s) for s in line["skills"]],
                task=line["task"],
                versions=dict(line["versions"]),
                metadata=dict(line["metadata"]),
            )
        )
    return records


def episode_summaries(root: Path | str) -> list[dict[str, Any]]:
    """The per-episode sidecar lines (seed, source, steps, success, skills, ...), without
    loading the frame data."""
    root = Path(root)
    read_kinder_meta(root)
    return _read_episode_lines(root)


__all__ = [
    "DEFAULT_FPS",
    "EPISODES_META",
    "KINDER_META",
    "DatasetError",
    "DemoWriter",
    "check_dataset",
    "dataset_features",
    "env_task",
    "episode_summaries",
    "image_key",
    "load_dataset",
    "load_records",
    "read_kinder_meta",
    "repo_id_for",
]
