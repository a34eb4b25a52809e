"""Splitting a Box vector into robot state and environment state, by name; demo camera images.

LeRobot's conventional keys separate ``observation.state`` (the robot's own features) from
``observation.environment_state`` (every other object's features). :class:`StateSplit` computes
that split from the env's object-centric layout: the Box view's feature names (``robot.x``,
``block0.theta``, ...) and the robot object(s), never from hard-coded index ranges. It is stored
with every dataset (``meta/kinder.json``), so a reader can split or join vectors without the env.

The robot objects are the Box view's objects whose type (or an ancestor type) has ``robot`` in its
name: ``crv_robot`` and ``kin_robot`` (2D), ``Kinematic3DRobot``, ``Dynamic3DRobot`` (3D). An env
whose robot type is named otherwise passes ``robot_objects`` explicitly.

:func:`camera_frames` is the one function that produces a dataset's images from a state, so that
training data and evaluation observations are made the same way: 2D envs have one camera,
``render`` (the env's render); 3D envs have ``base``, ``wrist`` and ``overview`` (the paper's
three cameras; for Dynamic3D the overview is the task's ``task_view`` camera and base/wrist are
``robot_base``/``robot_wrist``). Every frame is resized to ``size × size`` (default 224, as in the
paper); like the upstream converter, a non-square render is resized, not padded, so 2D frames
of non-square worlds are stretched. 3D envs are asked to render at ``size × size`` directly
(:func:`image_env_kwargs`), which keeps each camera's vertical field of view and is much cheaper
than rendering at the default size and resizing.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinder_core import ObjectCentricEnv, ObjectCentricState
from kinder_core.objects import Type

#: The default image size (pixels per side), as in the paper.
IMAGE_SIZE = 224
#: Camera names of 2D and 3D envs.
CAMERAS_2D = ("render",)
CAMERAS_3D = ("base", "wrist", "overview")
# Dynamic3D's camera names for the paper's three cameras.
_DYNAMIC3D_CAMERAS = {"base": "robot_base", "wrist": "robot_wrist", "overview": "task_view"}


def _unwrap(env: gymnasium.Env[Any, Any] | ObjectCentricEnv) -> ObjectCentricEnv:
    model = env.unwrapped
    if not isinstance(model, ObjectCentricEnv):
        raise TypeError(
            f"Expected a KinDER env (ObjectCentricEnv behind the wrappers), got "
            f"{type(model).__name__}"
        )
    return model


def is_robot_type(t: Type) -> bool:
    """Whether ``t`` or one of its ancestors has ``robot`` in its name (case-insensitive)."""
    current: Type | None = t
    while current is not None:
        if "robot" in current.name.lower():
            return True
        current = current.parent
    return False


@dataclasses.dataclass(frozen=True)
class StateSplit:
    """The robot / environment split of a Box vector, computed from feature names.

    Args:
        feature_names: The Box view's feature names in vector order (``"<object>.<feature>"``).
        robot_objects: The names of the robot object(s).
    """

    feature_names: tuple[str, ...]
    robot_objects: tuple[str, ...]

    def __post_init__(self) -> None:
        objects = {name.split(".", 1)[0] for name in self.feature_names}
        if any("." not in name for name in self.feature_names):
            bad = [n for n in self.feature_names if "." not in n][:3]
            raise ValueError(f"Feature names must look like '<object>.<feature>', got {bad}")
        missing = [o for o in self.robot_objects if o not in objects]
        if missing or not self.robot_objects:
            raise ValueError(
                f"Robot object(s) {list(self.robot_objects)} must be non-empty and among the "
                f"vector's objects {sorted(objects)}; missing {missing}"
            )

    @classmethod
    def from_env(
        cls,
        env: gymnasium.Env[Any, Any] | ObjectCentricEnv,
        robot_objects: Sequence[str] | None = None,
    ) -> StateSplit:
        """The split of ``env``'s Box view; robot objects found by type name unless given."""
        box = _unwrap(env).box_space
        if robot_objects is None:
            robot_objects = [o.name for o in box.objects if is_robot_type(o.type)]
            if not robot_objects:
                raise ValueError(
                    f"{_unwrap(env).env_name}: no object has a robot type (types "
                    f"{sorted({o.type.name for o in box.objects})}); pass robot_objects"
                )
        return cls(tuple(box.feature_names), tuple(robot_objects))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> StateSplit:
        return cls(tuple(data["feature_names"]), tuple(data["robot_objects"]))

    def to_dict(self) -> dict[str, Any]:
        return {
            "feature_names": list(self.feature_names),
            "robot_objects": list(self.robot_objects),
        }

    def _is_robot(self, name: str) -> bool:
        return name.split(".", 1)[0] in self.robot_objects

    @property
    def state_indices(self) -> NDArray[np.intp]:
        """Indices of the robot's features in the full vector."""
        return np.asarray(
            [i for i, n in enumerate(self.feature_names) if self._is_robot(n)], dtype=np.intp
        )

    @property
    def env_indices(self) -> NDArray[np.intp]:
        """Indices of every other feature in the full vector."""
        return np.asarray(
            [i for i, n in enumerate(self.feature_names) if not self._is_robot(n)], dtype=np.intp
        )

    @property
    def state_names(self) -> list[str]:
        return [self.feature_names[i] for i in self.state_indices]

    @property
    def env_names(self) -> list[str]:
        return [self.feature_names[i] for i in self.env_indices]

    @property
    def dim(self) -> int:
        return len(self.feature_names)

    def split(self, vectors: ArrayLike) -> tuple[NDArray[Any], NDArray[Any]]:
        """``(state, environment_state)`` of one vector or a ``(..., D)`` array of them."""
        v = np.asarray(vectors)
        if v.shape[-1:] != (self.dim,):
            raise ValueError(f"Expected vectors with last dimension {self.dim}, got {v.shape}")
        return v[..., self.state_indices], v[..., self.env_indices]

    def join(self, state: ArrayLike, environment_state: ArrayLike) -> NDArray[Any]:
        """The full vector(s) from the two parts (the inverse of :meth:`split`)."""
        s, e = np.asarray(state), np.asarray(environment_state)
        if s.shape[-1:] != (len(self.state_indices),) or e.shape[-1:] != (len(self.env_indices),):
            raise ValueError(
                f"Expected state (..., {len(self.state_indices)}) and environment state "
                f"(..., {len(self.env_indices)}), got {s.shape} and {e.shape}"
            )
        out = np.empty((*s.shape[:-1], self.dim), dtype=np.result_type(s, e))
        out[..., self.state_indices] = s
        out[..., self.env_indices] = e
        return out


def is_3d(env: gymnasium.Env[Any, Any] | ObjectCentricEnv) -> bool:
    """Whether the env has the 3D robot's cameras (``render_cameras``)."""
    return hasattr(_unwrap(env), "render_cameras")


def camera_names(env: gymnasium.Env[Any, Any] | ObjectCentricEnv) -> tuple[str, ...]:
    """The dataset camera names of an env (module docstring)."""
    return CAMERAS_3D if is_3d(env) else CAMERAS_2D


def image_env_kwargs(env_id: str, size: int = IMAGE_SIZE) -> dict[str, Any]:
    """Keyword arguments for ``kinder_core.make`` that make a 3D env render ``size × size``
    frames (empty for other envs). Kinematic3D's config is replaced after construction instead
    (see :func:`set_render_size`)."""
    from kinder_core.registration import ensure_registered

    ensure_registered(env_id)
    entry = str(gymnasium.spec(env_id).kwargs.get("env_entry_point", ""))
    if "dynamic3d" in entry:
        return {"config": {"image_width": size, "image_height": size}}
    return {}


def set_render_size(env: gymnasium.Env[Any, Any] | ObjectCentricEnv, size: int) -> None:
    """Make a Kinematic3D env render ``size × size`` frames (no effect on other envs)."""
    model = _unwrap(env)
    config = getattr(model, "config", None)
    if (
        not is_3d(model)
        or hasattr(model, "scene")  # Dynamic3D sizes its buffers at construction
        or config is None
        or isinstance(config, type)
        or not dataclasses.is_dataclass(config)
        or not hasattr(config, "image_width")
    ):
        return
    new_config = dataclasses.replace(config, image_width=size, image_height=size)  # type: ignore[type-var]
    model.config = new_config  # type: ignore[attr-defined]


def resize(frame: NDArray[np.uint8], size: int) -> NDArray[np.uint8]:
    """An H×W×3 frame resized to ``size × size`` (bilinear; unchanged when already that size)."""
    if frame.shape[:2] == (size, size):
        return np.ascontiguousarray(frame[..., :3])
    from PIL import Image

    img = Image.fromarray(np.ascontiguousarray(frame[..., :3]))
    return np.asarray(img.resize((size, size), Image.Resampling.BILINEAR), dtype=np.uint8)


def camera_frames(
    env: gymnasium.Env[Any, Any] | ObjectCentricEnv,
    state: ObjectCentricState | ArrayLike,
    size: int = IMAGE_SIZE,
) -> dict[str, NDArray[np.uint8]]:
    """The dataset images of ``state`` (a state or a Box vector), one per camera, each
    ``size × size × 3`` uint8. Rendering does not change the live episode."""
    model = _unwrap(env)
    if not isinstance(state, ObjectCentricState):
        state = model.box_space.devectorize(state)
    if not is_3d(model):
        return {"render": resize(model.render_state(state), size)}
    render_one = getattr(model, "_render_camera", None)
    if render_one is not None:  # Dynamic3D: render only the three cameras (it has more)
        names = list(getattr(model, "camera_names", []))
        frames = {c: render_one(state, c) for c in _DYNAMIC3D_CAMERAS.values() if c in names}
    else:
        frames = model.render_cameras(state)  # type: ignore[attr-defined]
    out = {}
    for name in CAMERAS_3D:
        key = name if name in frames else _DYNAMIC3D_CAMERAS[name]
        if key not in frames:
            raise KeyError(
                f"{model.env_name}: the cameras are {sorted(frames)}, expected {name!r} or "
                f"{_DYNAMIC3D_CAMERAS[name]!r}"
            )
        out[name] = resize(frames[key], size)
    return out
