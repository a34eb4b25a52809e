"""Reading KinDER demonstration datasets (LeRobotDataset v3) for the learning baselines.

The demonstrations issue writes one LeRobot v3 dataset per env with these features:

* ``observation.state`` (float32): the robot's features, ``names`` like ``robot.x``;
* ``observation.environment_state`` (float32): every other feature of the Box observation;
* ``observation.images.<camera>`` (video): ``render`` for 2D envs; ``base``, ``wrist`` and
  ``overview`` (224×224) for 3D envs;
* ``action`` (float32), ``next.reward``, ``next.done`` and the ``task`` string.

:func:`read_dataset_spec` reads what the baselines need from ``meta/info.json`` without decoding
anything; :func:`read_episodes` reads the state and action columns straight from the parquet
files (no video decoding, no lerobot import), which is all MBRL needs. :class:`ObservationMap`
turns a live env state back into the dataset's features (state slices by feature *name*, camera
images rendered and resized to the dataset's shape), so a policy trained on one env can be
evaluated on another one that has the same robot and cameras (the paper's DynObstruction2D OOD
evaluation).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_core import ObjectCentricEnv, ObjectCentricState

STATE_KEY = "observation.state"
ENV_STATE_KEY = "observation.environment_state"
IMAGE_PREFIX = "observation.images."
ACTION_KEY = "action"

#: Camera name in the dataset → the names an env may give that camera, in order of preference.
CAMERA_ALIASES: dict[str, tuple[str, ...]] = {
    "render": (),  # the env's own render (2D envs)
    "overview": ("overview", "task_view"),
    "base": ("base", "robot_base"),
    "wrist": ("wrist", "robot_wrist"),
}


def _feature_names(feature: Mapping[str, Any], key: str) -> tuple[str, ...]:
    names = feature.get("names")
    if isinstance(names, Mapping):  # lerobot also accepts {"axes": [...]}
        values = list(names.values())
        names = values[0] if len(values) == 1 else None
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise ValueError(
            f"Dataset feature {key!r} must list its feature names (e.g. 'robot.x'); got {names!r}"
        )
    shape = tuple(feature.get("shape", ()))
    if shape != (len(names),):
        raise ValueError(
            f"Dataset feature {key!r}: shape {shape} does not match its {len(names)} names"
        )
    return tuple(names)


@dataclasses.dataclass(frozen=True)
class DatasetSpec:
    """What a demonstration dataset holds (from ``meta/info.json``)."""

    root: Path
    """The dataset directory."""
    env_id: str | None
    """The env the demos come from (``info.json``'s ``robot_type`` when it names an env id)."""
    fps: int
    """Frames per second (a label: KinDER envs are not timed)."""
    state_names: tuple[str, ...]
    """Names of the ``observation.state`` entries (the robot's features)."""
    env_state_names: tuple[str, ...]
    """Names of the ``observation.environment_state`` entries (empty when absent)."""
    action_dim: int
    """Size of the action vector."""
    cameras: tuple[str, ...]
    """Camera names (the ``<camera>`` of ``observation.images.<camera>``), sorted."""
    image_shape: tuple[int, int, int] | None
    """``(height, width, channels)`` of every camera (None without cameras)."""
    num_episodes: int
    """Episodes in the dataset."""
    num_frames: int
    """Frames (= steps) in the dataset."""

    @property
    def image_keys(self) -> tuple[str, ...]:
        return tuple(IMAGE_PREFIX + c for c in self.cameras)


def read_dataset_spec(root: Path | str) -> DatasetSpec:
    """Read a dataset's :class:`DatasetSpec`; a clear error when it is not a KinDER dataset."""
    root = Path(root)
    info_path = root / "meta" / "info.json"
    if not info_path.is_file():
        raise FileNotFoundError(
            f"{root} is not a LeRobot dataset (no meta/info.json); expected a directory written "
            f"by kinder_gym.demos.lerobot_format"
        )
    info = json.loads(info_path.read_text())
    features: dict[str, Any] = info.get("features", {})
    missing = [k for k in (STATE_KEY, ACTION_KEY) if k not in features]
    if missing:
        raise ValueError(f"{root}: dataset lacks the feature(s) {missing}; has {sorted(features)}")
    state_names = _feature_names(features[STATE_KEY], STATE_KEY)
    env_state_names = (
        _feature_names(features[ENV_STATE_KEY], ENV_STATE_KEY) if ENV_STATE_KEY in features else ()
    )
    cameras = tuple(sorted(k[len(IMAGE_PREFIX) :] for k in features if k.startswith(IMAGE_PREFIX)))
    shapes = {tuple(features[IMAGE_PREFIX + c]["shape"]) for c in cameras}
    if len(shapes) > 1:
        raise ValueError(f"{root}: cameras must share one image shape, got {sorted(shapes)}")
    image_shape = None
    if shapes:
        (shape,) = shapes
        if len(shape) != 3 or shape[2] != 3:
            raise ValueError(f"{root}: expected (height, width, 3) images, got {shape}")
        image_shape = (int(shape[0]), int(shape[1]), int(shape[2]))
    robot_type = info.get("robot_type")
    env_id = (
        robot_type if isinstance(robot_type, str) and robot_type.startswith("kinder/") else None
    )
    return DatasetSpec(
        root=root,
        env_id=env_id,
        fps=int(info.get("fps", 10)),
        state_names=state_names,
        env_state_names=env_state_names,
        action_dim=int(features[ACTION_KEY]["shape"][0]),
        cameras=cameras,
        image_shape=image_shape,
        num_episodes=int(info.get("total_episodes", 0)),
        num_frames=int(info.get("total_frames", 0)),
    )


def resolve_dataset_env(spec: DatasetSpec, env_id: str | None) -> str:
    """The env id to train for: ``env_id`` when given (it must agree with the dataset's), else
    the dataset's own."""
    from kinder_bench.envs import resolve_env_id

    if env_id is not None:
        resolved = resolve_env_id(env_id)
        if spec.env_id is not None and spec.env_id != resolved:
            raise ValueError(f"{spec.root} holds demos of {spec.env_id}, not {resolved}")
        return resolved
    if spec.env_id is None:
        raise ValueError(
            f"{spec.root}: the dataset does not name its env (info.json robot_type); pass --env"
        )
    return resolve_env_id(spec.env_id)


@dataclasses.dataclass(frozen=True)
class EpisodeArrays:
    """One episode's state and action columns (``T`` frames)."""

    index: int
    state: NDArray[np.float32]
    """``(T, robot dims)``."""
    env_state: NDArray[np.float32]
    """``(T, env dims)`` (``(T, 0)`` when the dataset has no environment state)."""
    action: NDArray[np.float32]
    """``(T, action dims)``."""


def read_columns(root: Path | str) -> dict[str, NDArray[Any]]:
    """The non-image columns every baseline reads, one row per frame in global ``index`` order:
    ``episode_index`` (int64), ``observation.state``, ``observation.environment_state`` (``(N,
    0)`` when absent) and ``action`` (float32), read straight from the parquet files under
    ``data/`` (no video decoding, no lerobot import)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    spec = read_dataset_spec(root)
    files = sorted((spec.root / "data").rglob("*.parquet"))
    if not files:
        raise FileNotFoundError(f"{spec.root}: no parquet files under data/")
    columns = ["index", "episode_index", STATE_KEY, ACTION_KEY]
    if spec.env_state_names:
        columns.append(ENV_STATE_KEY)
    table = pa.concat_tables([pq.read_table(f, columns=columns) for f in files])
    table = table.take(pc.sort_indices(table, sort_keys=[("index", "ascending")]))

    def column(key: str, width: int) -> NDArray[np.float32]:
        values = table.column(key).to_pylist()
        return np.asarray(values, dtype=np.float32).reshape(len(values), width)

    episode = np.asarray(table.column("episode_index").to_pylist(), dtype=np.int64)
    return {
        "episode_index": episode,
        STATE_KEY: column(STATE_KEY, len(spec.state_names)),
        ENV_STATE_KEY: (
            column(ENV_STATE_KEY, len(spec.env_state_names))
            if spec.env_state_names
            else np.zeros((len(episode), 0), dtype=np.float32)
        ),
        ACTION_KEY: column(ACTION_KEY, spec.action_dim),
    }


def read_episodes(root: Path | str) -> list[EpisodeArrays]:
    """Every episode's state, environment-state and action columns (see :func:`read_columns`)."""
    cols = read_columns(root)
    episode = cols["episode_index"]
    out = []
    for e in np.unique(episode):
        rows = episode == e
        out.append(
            EpisodeArrays(
                int(e), cols[STATE_KEY][rows], cols[ENV_STATE_KEY][rows], cols[ACTION_KEY][rows]
            )
        )
    return out


def _resize(image: NDArray[np.uint8], height: int, width: int) -> NDArray[np.uint8]:
    if image.shape[:2] == (height, width):
        return image
    from PIL import Image

    resized = Image.fromarray(image).resize((width, height), Image.Resampling.BILINEAR)
    return np.asarray(resized, dtype=np.uint8)


def camera_images(
    model: ObjectCentricEnv,
    state: ObjectCentricState,
    cameras: Sequence[str],
    shape: tuple[int, int, int],
) -> dict[str, NDArray[np.uint8]]:
    """Images of ``state`` from ``cameras`` (dataset names), resized (bilinear) to ``shape``.

    ``render`` is the env's own render; ``overview``/``base``/``wrist`` come from the env's
    ``render_cameras`` (3D envs), matched through :data:`CAMERA_ALIASES`.
    """
    images: dict[str, NDArray[np.uint8]] = {}
    rendered: dict[str, NDArray[np.uint8]] | None = None
    for camera in cameras:
        if camera == "render":
            frame = model.render_state(state)
        else:
            if rendered is None:
                render_cameras = getattr(model, "render_cameras", None)
                if render_cameras is None:
                    raise ValueError(
                        f"{model.env_name} has no cameras; the policy needs {camera!r}"
                    )
                rendered = dict(render_cameras(state))
            names = [n for n in CAMERA_ALIASES.get(camera, (camera,)) if n in rendered]
            if not names:
                raise ValueError(
                    f"{model.env_name} has no camera {camera!r}; its cameras: {sorted(rendered)}"
                )
            frame = rendered[names[0]]
        images[camera] = _resize(np.asarray(frame, dtype=np.uint8), shape[0], shape[1])
    return images


class ObservationMap:
    """Builds a policy's inputs (the dataset's features) from a live env's states.

    Args:
        env: The evaluation env (its ``unwrapped`` is the object-centric model).
        state_names: The ``observation.state`` feature names the policy was trained on.
        env_state_names: The ``observation.environment_state`` names (empty: not an input).
        cameras: Camera names (empty: no images).
        image_shape: ``(height, width, 3)`` of the training images.

    Raises:
        ValueError: when the env lacks a feature the policy needs (naming the missing ones).
    """

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        state_names: Sequence[str],
        env_state_names: Sequence[str] = (),
        cameras: Sequence[str] = (),
        image_shape: tuple[int, int, int] | None = None,
    ) -> None:
        model = env.unwrapped
        if not isinstance(model, ObjectCentricEnv):
            raise TypeError(f"ObservationMap needs a KinDER env, got {type(model).__name__}")
        self.model = model
        names = model.box_space.feature_names
        position = {n: i for i, n in enumerate(names)}
        for what, wanted in (("robot state", state_names), ("environment state", env_state_names)):
            missing = [n for n in wanted if n not in position]
            if missing:
                raise ValueError(
                    f"{model.env_name} lacks {len(missing)} {what} feature(s) the policy was "
                    f"trained on, e.g. {missing[:5]}"
                )
        self.state_index = np.asarray([position[n] for n in state_names], dtype=np.intp)
        self.env_state_index = np.asarray([position[n] for n in env_state_names], dtype=np.intp)
        if cameras and image_shape is None:
            raise ValueError("ObservationMap: cameras need an image_shape")
        self.cameras = tuple(cameras)
        self.image_shape = image_shape

    def features(self, state: ObjectCentricState) -> dict[str, NDArray[Any]]:
        """The dataset features of ``state``: float32 vectors and uint8 (H, W, 3) images."""
        vec = self.model.box_space.vectorize(state).astype(np.float32)
        out: dict[str, NDArray[Any]] = {STATE_KEY: vec[self.state_index]}
        if len(self.env_state_index):
            out[ENV_STATE_KEY] = vec[self.env_state_index]
        if self.cameras:
            assert self.image_shape is not None
            images = camera_images(self.model, state, self.cameras, self.image_shape)
            out.update({IMAGE_PREFIX + c: img for c, img in images.items()})
        return out
