"""Export a KinDER demonstration dataset to the LeRobot layout openpi's data loader reads.

openpi (``Physical-Intelligence/openpi``) pins lerobot at git commit ``0cf8648`` (May 2025),
whose ``LeRobotDataset`` reads **LeRobotDataset v2.1** (``CODEBASE_VERSION = "v2.1"``) and
refuses v3.0 datasets like ours. Its ``datasets`` is 3.6 and its numpy < 2, so the parquet files
are written here with pyarrow and the ``datasets`` 3.x feature schema, not with our (newer)
``datasets``, whose ``List`` feature type that version cannot read.

Layout written under ``OUT`` (every path is what lerobot v2.1 reads)::

    meta/info.json              codebase_version "v2.1", fps, features, counts, path templates
    meta/episodes.jsonl         {"episode_index", "tasks": [task], "length"} per episode
    meta/tasks.jsonl            {"task_index", "task"} (one task: the env's goal text)
    meta/episodes_stats.jsonl   {"episode_index", "stats": {key: {min, max, mean, std, count}}}
    meta/kinder_openpi.json     KinDER sidecar (source dataset, env id, key map, feature names)
    data/chunk-000/episode_000000.parquet, ...   one parquet file per episode, 1000 per chunk

**Per-frame columns** (frame ``t`` is the observation before action ``t``, as in our datasets):

===================== ================ ====================================================
key                   dtype (shape)    content
===================== ================ ====================================================
``base_0_rgb``        image (H, W, 3)  2D: the env render; 3D: the base camera
``left_wrist_0_rgb``  image (H, W, 3)  3D only: the wrist camera
``right_wrist_0_rgb`` image (H, W, 3)  3D only: the overview camera
``state``             float32 (S,)     the robot's features (our ``observation.state``)
``environment_state`` float32 (E,)     every other feature (``observation.environment_state``)
``actions``           float32 (A,)     the action (our ``action``)
``timestamp``         float32          ``frame_index / fps``
``frame_index``       int64            step within the episode
``episode_index``     int64            episode number
``index``             int64            frame number in the whole dataset
``task_index``        int64            index into ``meta/tasks.jsonl`` (always 0)
===================== ================ ====================================================

The image keys are the request keys of upstream KinDER's openpi bridge and of the ``vla`` agent
(``kinder_bench.baselines.vla``), ``state`` and ``actions`` are openpi's conventional names (its
default ``action_sequence_keys`` is ``("actions",)``), and the task text becomes the prompt with
``DataConfig(prompt_from_task=True)``. Images are stored as lerobot v2.1 ``image`` features: PNG
bytes in the parquet file (a ``{bytes, path}`` struct, ``path`` null), which openpi's examples
also use, so no video decoder is involved on the training machine.

Choices, written down:

* **Images are rendered from the recorded states** with
  :func:`~kinder_gym.demos.layout.camera_frames` (the renderer that made the dataset's video
  frames and that the ``vla`` agent uses at evaluation), not decoded from the dataset's AV1
  videos: the exported pixels are exactly what a served policy is sent at evaluation, with no
  compression loss. The cost is rendering time (3D envs render three cameras per frame).
* **Statistics** in ``episodes_stats.jsonl`` are computed over every frame (lerobot v2.1 samples
  image frames); image statistics are per channel in [0, 1], shape (3, 1, 1), as v2.1 writes
  them. openpi does not use them (``scripts/compute_norm_stats.py`` computes its own); lerobot
  reads and aggregates them when it opens the dataset.
* ``robot_type`` is ``"kinder"``; no ``stats.json`` is written (v2.1 reads the episode stats).

The export is written to a sibling directory ``.OUT.openpi-partial`` and moved into place at the
end, so an interrupted export never leaves a half-written ``OUT``; it is also **resumable**:
rerunning the same export (same source dataset, selection and ``images``) keeps the episodes
already written there (each episode's parquet file and statistics are written atomically) and
continues from the first missing one. A different export into the same ``OUT`` starts afresh.
"""

from __future__ import annotations

import dataclasses
import functools
import io
import json
import math
import os
import shutil
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinder_gym.demos.layout import (
    CAMERAS_2D,
    CAMERAS_3D,
    StateSplit,
    camera_frames,
    camera_names,
    image_env_kwargs,
    set_render_size,
)
from kinder_gym.demos.record import EpisodeRecord

CODEBASE_VERSION = "v2.1"
CHUNK_SIZE = 1000
DATA_PATH = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet"
SIDECAR = "meta/kinder_openpi.json"
PARTIAL = "kinder_openpi_partial.json"
EPISODE_STATS = "episode_stats"
EXPORT_VERSION = 1

#: Our camera names → the exported image keys (upstream KinDER's openpi request keys).
IMAGE_KEYS: dict[str, str] = {
    CAMERAS_2D[0]: "base_0_rgb",
    CAMERAS_3D[0]: "base_0_rgb",
    CAMERAS_3D[1]: "left_wrist_0_rgb",
    CAMERAS_3D[2]: "right_wrist_0_rgb",
}
STATE = "state"
ENV_STATE = "environment_state"
ACTIONS = "actions"
#: lerobot v2.1's bookkeeping columns, in its order.
INDEX_COLUMNS = ("timestamp", "frame_index", "episode_index", "index", "task_index")


class ExportError(ValueError):
    """The source dataset cannot be exported or the output directory is unusable."""


@dataclasses.dataclass(frozen=True)
class ExportSummary:
    """What :func:`export_openpi` wrote."""

    out: Path
    env_id: str
    episodes: int
    frames: int
    image_keys: tuple[str, ...]
    state_dim: int
    env_state_dim: int
    action_dim: int
    fps: int
    task: str


def _vector_feature(dtype: str, names: Sequence[str]) -> dict[str, Any]:
    return {"dtype": dtype, "shape": [len(names)], "names": list(names)}


def openpi_features(
    split: StateSplit, action_dim: int, image_keys: Sequence[str], image_size: int
) -> dict[str, dict[str, Any]]:
    """The ``features`` of ``meta/info.json`` (lerobot v2.1 spelling)."""
    features: dict[str, dict[str, Any]] = {}
    for key in image_keys:
        features[key] = {
            "dtype": "image",
            "shape": [image_size, image_size, 3],
            "names": ["height", "width", "channel"],
        }
    features[STATE] = _vector_feature("float32", split.state_names)
    features[ENV_STATE] = _vector_feature("float32", split.env_names)
    features[ACTIONS] = _vector_feature("float32", [f"action{i}" for i in range(action_dim)])
    features["timestamp"] = {"dtype": "float32", "shape": [1], "names": None}
    for key in INDEX_COLUMNS[1:]:
        features[key] = {"dtype": "int64", "shape": [1], "names": None}
    return features


def hf_features(features: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """The ``datasets`` 3.x ``Features`` dict (``Value``, ``Sequence``, ``Image``) that goes in
    each parquet file's ``huggingface`` schema metadata, as lerobot v2.1 maps features to it."""
    out: dict[str, Any] = {}
    for key, ft in features.items():
        if ft["dtype"] == "image":
            out[key] = {"_type": "Image"}
        elif list(ft["shape"]) == [1]:
            out[key] = {"dtype": ft["dtype"], "_type": "Value"}
        else:
            out[key] = {
                "feature": {"dtype": ft["dtype"], "_type": "Value"},
                "length": int(ft["shape"][0]),
                "_type": "Sequence",
            }
    return out


def _png(image: NDArray[np.uint8]) -> bytes:
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()


def _episode_table(
    columns: Mapping[str, Any], features: Mapping[str, Mapping[str, Any]], metadata: bytes
) -> Any:
    import pyarrow as pa

    arrays, fields = [], []
    for key, ft in features.items():
        value = columns[key]
        if ft["dtype"] == "image":
            kind = pa.struct([("bytes", pa.binary()), ("path", pa.string())])
            array = pa.array([{"bytes": b, "path": None} for b in value], type=kind)
        elif list(ft["shape"]) == [1]:
            array = pa.array(np.asarray(value, dtype=ft["dtype"]).reshape(-1))
        else:
            flat = np.ascontiguousarray(value, dtype=ft["dtype"]).reshape(-1)
            array = pa.FixedSizeListArray.from_arrays(pa.array(flat), int(ft["shape"][0]))
        arrays.append(array)
        fields.append(pa.field(key, array.type))
    schema = pa.schema(fields, metadata={b"huggingface": metadata})
    return pa.Table.from_arrays(arrays, schema=schema)


def _stats(values: NDArray[Any]) -> dict[str, Any]:
    """lerobot v2.1's per-episode statistics of one feature (vectors over axis 0, keeping a
    (1,) shape for scalars; images per channel in [0, 1] as (3, 1, 1))."""
    if values.ndim == 4:  # images (T, H, W, 3) uint8
        data = values.astype(np.float64) / 255.0
        axes: tuple[int, ...] = (0, 1, 2)
        reshape: tuple[int, ...] = (3, 1, 1)
    else:
        data = values.astype(np.float64).reshape(len(values), -1)
        axes, reshape = (0,), (data.shape[1],)
    return {
        "min": np.min(data, axis=axes).reshape(reshape).tolist(),
        "max": np.max(data, axis=axes).reshape(reshape).tolist(),
        "mean": np.mean(data, axis=axes).reshape(reshape).tolist(),
        "std": np.std(data, axis=axes).reshape(reshape).tolist(),
        "count": [len(values)],
    }


def _write_json(path: Path, obj: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=4) + "\n")


def _write_jsonl(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(json.dumps(row) + "\n" for row in rows))


def _prepare_out(out: Path, overwrite: bool, key: Mapping[str, Any]) -> Path:
    """The partial directory to export into: kept from an interrupted export of the same
    ``key`` (source, selection, images), otherwise made empty."""
    if out.exists() and not out.is_dir():
        raise ExportError(f"{out}: exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise ExportError(
            f"{out}: exists and is not empty; choose a new directory or pass overwrite "
            f"(--overwrite) to replace it"
        )
    tmp = out.with_name(f".{out.name}.openpi-partial")
    marker = tmp / PARTIAL
    if tmp.exists():
        try:
            same = json.loads(marker.read_text()) == json.loads(json.dumps(key))
        except (OSError, json.JSONDecodeError):
            same = False
        if same:
            return tmp
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    _write_json(marker, key)
    return tmp


def _write_atomic(path: Path, write: Callable[[Path], None]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    part = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    write(part)
    os.replace(part, path)


def _commit(tmp: Path, out: Path) -> None:
    (tmp / PARTIAL).unlink()
    shutil.rmtree(tmp / EPISODE_STATS, ignore_errors=True)
    old = out.with_name(f".{out.name}.openpi-old-{os.getpid()}")
    if out.exists():
        os.replace(out, old)
    os.replace(tmp, out)
    if old.exists():
        shutil.rmtree(old)


def export_openpi(
    dataset: Path | str,
    out: Path | str,
    *,
    images: bool = True,
    overwrite: bool = False,
    episodes: Sequence[int] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ExportSummary:
    """Write the openpi (LeRobot v2.1) export of a KinDER dataset to ``out`` (module docstring).

    Args:
        dataset: A KinDER LeRobotDataset v3 directory (``kinder demos build``).
        out: The export directory (missing or empty; ``overwrite`` replaces an existing one).
        images: Render the camera images (False: state-only export, e.g. for tests).
        overwrite: Replace a non-empty ``out`` (only once the new export is complete).
        episodes: Export only these episode indices (default: all), renumbered from 0.
        progress: Called with (episodes done, episodes total) after each episode.

    Raises:
        ExportError: ``out`` is unusable or the dataset has no episodes.
        DatasetError: the source dataset is missing or corrupt (names the file).
    """
    import kinder_core
    from kinder_gym.demos.lerobot_format import load_records, read_kinder_meta

    dataset, out = Path(dataset), Path(out)
    meta = read_kinder_meta(dataset)
    records = load_records(dataset, episodes=episodes)
    if not records:
        raise ExportError(f"{dataset}: no episodes to export")
    env_id = str(meta["env_id"])
    split = StateSplit.from_dict(meta["split"])
    action_dim = int(meta["action_dim"])
    fps = int(meta["fps"])
    size = int(meta.get("image_size", 224))
    task = records[0].task or str(meta.get("task", ""))
    env: Any = None
    cameras: tuple[str, ...] = ()
    if images:
        env = kinder_core.make(env_id, render_mode="rgb_array", **image_env_kwargs(env_id, size))
        set_render_size(env, size)
        cameras = camera_names(env)
    image_keys = tuple(IMAGE_KEYS[c] for c in cameras)
    features = openpi_features(split, action_dim, image_keys, size)
    metadata = json.dumps({"info": {"features": hf_features(features)}}).encode()

    import pyarrow.parquet as pq

    resume_key = {
        "export_version": EXPORT_VERSION,
        "source": str(dataset.resolve()),
        "source_info_mtime_ns": (dataset / "meta" / "info.json").stat().st_mtime_ns,
        "episodes": None if episodes is None else [int(e) for e in episodes],
        "images": images,
    }
    tmp = _prepare_out(out, overwrite, resume_key)
    try:
        lengths, stats_lines, total = [], [], 0
        for i, record in enumerate(records):
            path = tmp / DATA_PATH.format(episode_chunk=i // CHUNK_SIZE, episode_index=i)
            stats_path = tmp / EPISODE_STATS / f"episode_{i:06d}.json"
            if not (path.exists() and stats_path.exists()):  # else done by an earlier run
                columns = _episode_columns(record, split, env, cameras, size, fps, i, total)
                table = _episode_table(
                    {k: v for k, v in columns.items() if k not in image_keys}
                    | {k: [_png(f) for f in columns[k]] for k in image_keys},
                    features,
                    metadata,
                )
                _write_atomic(path, functools.partial(pq.write_table, table))
                stats = {k: _stats(np.asarray(columns[k])) for k in features}
                _write_atomic(stats_path, functools.partial(_write_json, obj=stats))
            stats_lines.append({"episode_index": i, "stats": json.loads(stats_path.read_text())})
            lengths.append(record.num_steps)
            total += record.num_steps
            if progress is not None:
                progress(i + 1, len(records))
        n = len(records)
        info = {
            "codebase_version": CODEBASE_VERSION,
            "robot_type": "kinder",
            "total_episodes": n,
            "total_frames": total,
            "total_tasks": 1,
            "total_videos": 0,
            "total_chunks": math.ceil(n / CHUNK_SIZE),
            "chunks_size": CHUNK_SIZE,
            "fps": fps,
            "splits": {"train": f"0:{n}"},
            "data_path": DATA_PATH,
            "video_path": None,
            "features": features,
        }
        _write_json(tmp / "meta" / "info.json", info)
        _write_jsonl(
            tmp / "meta" / "episodes.jsonl",
            [{"episode_index": i, "tasks": [task], "length": t} for i, t in enumerate(lengths)],
        )
        _write_jsonl(tmp / "meta" / "tasks.jsonl", [{"task_index": 0, "task": task}])
        _write_jsonl(tmp / "meta" / "episodes_stats.jsonl", stats_lines)
        _write_json(
            tmp / SIDECAR,
            {
                "export_version": EXPORT_VERSION,
                "source": str(dataset.resolve()),
                "env_id": env_id,
                "cameras": {c: IMAGE_KEYS[c] for c in cameras},
                "state_names": list(split.state_names),
                "environment_state_names": list(split.env_names),
                "action_dim": action_dim,
                "source_episode_seeds": [int(r.seed) for r in records],
            },
        )
        _commit(tmp, out)
    finally:
        if env is not None:
            env.close()
    return ExportSummary(
        out, env_id, len(records), total, image_keys, len(split.state_names),
        len(split.env_names), action_dim, fps, task,
    )  # fmt: skip


def _episode_columns(
    record: EpisodeRecord,
    split: StateSplit,
    env: Any,
    cameras: Sequence[str],
    size: int,
    fps: int,
    episode: int,
    first_index: int,
) -> dict[str, Any]:
    """The columns of one episode (images as uint8 arrays)."""
    steps = record.num_steps
    state, env_state = split.split(record.observations[:-1])
    frame_index = np.arange(steps, dtype=np.int64)
    columns: dict[str, Any] = {
        STATE: np.asarray(state, dtype=np.float32),
        ENV_STATE: np.asarray(env_state, dtype=np.float32),
        ACTIONS: np.asarray(record.actions, dtype=np.float32),
        "timestamp": (frame_index / fps).astype(np.float32),
        "frame_index": frame_index,
        "episode_index": np.full(steps, episode, dtype=np.int64),
        "index": first_index + frame_index,
        "task_index": np.zeros(steps, dtype=np.int64),
    }
    if cameras:
        states = record.states
        if states is None:
            from kinder_gym.demos.replay import replay_states

            states = replay_states(env, record)
        frames: dict[str, list[NDArray[np.uint8]]] = {IMAGE_KEYS[c]: [] for c in cameras}
        for t in range(steps):
            for cam, image in camera_frames(env, states[t], size).items():
                frames[IMAGE_KEYS[cam]].append(image)
        columns.update({k: np.stack(v) for k, v in frames.items()})
    return columns
