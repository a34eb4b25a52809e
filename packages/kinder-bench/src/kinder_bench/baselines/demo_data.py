"""What the learning baselines need from a KinDER demonstration dataset, and back from an env.

The datasets are LeRobotDataset v3 directories written by
:class:`kinder_gym.demos.lerobot_format.DemoWriter` (``observation.state``: the robot's
features; ``observation.environment_state``: every other feature; ``observation.images.<camera>``:
``render`` in 2D, ``base``/``wrist``/``overview`` in 3D; ``action``; the KinDER sidecar
``meta/kinder.json`` with the env id and the :class:`~kinder_gym.demos.layout.StateSplit`).

:func:`read_dataset_spec` reads the sidecar and ``meta/info.json`` (nothing is decoded).
:class:`ObservationMap` turns a live env state back into the dataset's features: the state
slices are taken by feature *name* (so a policy trained on one env can be evaluated on another
with the same robot and cameras, the paper's DynObstruction2D OOD test) and the images come from
:func:`kinder_gym.demos.layout.camera_frames`, the function that rendered the training images.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_core import ObjectCentricEnv, ObjectCentricState
from kinder_gym.demos.layout import StateSplit, camera_frames, set_render_size

STATE_KEY = "observation.state"
ENV_STATE_KEY = "observation.environment_state"
IMAGE_PREFIX = "observation.images."
ACTION_KEY = "action"


@dataclasses.dataclass(frozen=True)
class DatasetSpec:
    """What a demonstration dataset holds (from ``meta/kinder.json`` and ``meta/info.json``)."""

    root: Path
    """The dataset directory."""
    env_id: str
    """The env the demos come from."""
    split: StateSplit
    """The full feature names and which of them are the robot's."""
    action_dim: int
    """Size of the action vector."""
    cameras: tuple[str, ...]
    """Camera names (the ``<camera>`` of ``observation.images.<camera>``)."""
    image_size: int
    """Pixels per side of every camera image."""
    num_episodes: int
    """Episodes in the dataset."""
    num_frames: int
    """Frames (= steps) in the dataset."""

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(self.split.state_names)

    @property
    def env_state_names(self) -> tuple[str, ...]:
        return tuple(self.split.env_names)

    @property
    def image_keys(self) -> tuple[str, ...]:
        return tuple(IMAGE_PREFIX + c for c in self.cameras)

    @property
    def image_shape(self) -> tuple[int, int, int] | None:
        return (self.image_size, self.image_size, 3) if self.cameras else None


def read_dataset_spec(root: Path | str) -> DatasetSpec:
    """The :class:`DatasetSpec` of a dataset; a clear error when it is not a KinDER dataset."""
    from kinder_gym.demos.lerobot_format import read_kinder_meta

    root = Path(root)
    if not (root / "meta" / "info.json").is_file():
        raise FileNotFoundError(
            f"{root} is not a LeRobot dataset (no meta/info.json); expected a directory written "
            f"by kinder_gym.demos.lerobot_format.DemoWriter (`kinder demos build`)"
        )
    meta = read_kinder_meta(root)
    info = json.loads((root / "meta" / "info.json").read_text())
    return DatasetSpec(
        root=root,
        env_id=str(meta["env_id"]),
        split=StateSplit.from_dict(meta["split"]),
        action_dim=int(meta["action_dim"]),
        cameras=tuple(meta.get("cameras", ())),
        image_size=int(meta.get("image_size", 224)),
        num_episodes=int(info.get("total_episodes", 0)),
        num_frames=int(info.get("total_frames", 0)),
    )


def resolve_dataset_env(spec: DatasetSpec, env_id: str | None) -> str:
    """The env id to train for: the dataset's; ``env_id``, when given, must name the same env."""
    from kinder_bench.evaluation.envs import resolve_env_id

    own = resolve_env_id(spec.env_id)
    if env_id is not None and resolve_env_id(env_id) != own:
        raise ValueError(f"{spec.root} holds demos of {own}, not {resolve_env_id(env_id)}")
    return own


class ObservationMap:
    """Builds a policy's inputs (the dataset's features) from a live env's states.

    Args:
        env: The evaluation env (its ``unwrapped`` is the object-centric model).
        state_names: The ``observation.state`` feature names the policy was trained on.
        env_state_names: The ``observation.environment_state`` names (empty: not an input).
        cameras: Camera names (empty: no images).
        image_size: Pixels per side of the training images. A Kinematic3D env is switched to
            render at this size, as the dataset writer does (it changes only rendering);
            Dynamic3D envs size their renderer when made, so their frames are rendered at the
            env's size and resized.

    Raises:
        ValueError: when the env lacks a feature the policy needs (naming the missing ones).
    """

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        state_names: Sequence[str],
        env_state_names: Sequence[str] = (),
        cameras: Sequence[str] = (),
        image_size: int = 224,
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
        self.cameras = tuple(cameras)
        self.image_size = image_size
        if self.cameras:
            set_render_size(model, image_size)

    def features(self, state: ObjectCentricState) -> dict[str, NDArray[Any]]:
        """The dataset features of ``state``: float32 vectors and uint8 (H, W, 3) images."""
        vec = self.model.box_space.vectorize(state).astype(np.float32)
        out: dict[str, NDArray[Any]] = {STATE_KEY: vec[self.state_index]}
        if len(self.env_state_index):
            out[ENV_STATE_KEY] = vec[self.env_state_index]
        if self.cameras:
            frames = camera_frames(self.model, state, self.image_size)
            missing = [c for c in self.cameras if c not in frames]
            if missing:
                raise ValueError(
                    f"{self.model.env_name} has no camera {missing}; it has {sorted(frames)}"
                )
            out.update({IMAGE_PREFIX + c: frames[c] for c in self.cameras})
        return out
