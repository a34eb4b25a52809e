"""The episode record: one type for every demonstration source (planner, script, teleoperation).

An :class:`EpisodeRecord` holds what one episode of one env produced: the env id, the package
versions and reset seed that produced it, the actions actually applied (after clipping to the
action bounds), the Box observations, rewards, termination flags, wall-clock timing, the source,
the object-centric state vectors (so states are recoverable without replay), and, for
skill-based sources, :class:`SkillLabel` s naming which skill covered which steps.

:class:`EpisodeRecorder` builds a record step by step around a live env; it is what collectors
and the teleoperation loop use. Storage formats (LeRobotDataset v3, the upstream pickle and HDF5
layouts) live in the sibling modules and all convert to and from this record.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import time
from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import ObjectCentricEnv

FloatArray = NDArray[np.float64]

#: Where a demonstration came from.
SOURCES = ("bilevel_planning", "mpc", "scripted", "teleop", "imported")

#: Packages whose versions every record carries: ours and the simulators beneath the envs (a
#: simulator's version can change an episode: MuJoCo 3.3 and 4.0 differ in box-box contact depth).
VERSIONED_PACKAGES = (
    "kinder-core",
    "kinder-garden2d",
    "kinder-garden3d",
    "kinder-gym",
    "gymnasium",
    "numpy",
    "pymunk",
    "pybullet",
    "mujoco",
    "mink",
)


def package_versions(names: Sequence[str] = VERSIONED_PACKAGES) -> dict[str, str]:
    """Installed versions of ``names`` (missing packages are left out)."""
    versions = {}
    for name in names:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return versions


@dataclasses.dataclass(frozen=True)
class SkillLabel:
    """One skill execution inside an episode: steps ``[start, end)`` were produced by it."""

    operator: str
    """The ground operator's name, e.g. ``"Pick"``."""
    objects: tuple[str, ...]
    """The names of the objects it was grounded on, in the operator's parameter order."""
    params: tuple[float, ...]
    """The continuous parameters the skill was reset with."""
    start: int
    """Index of the first step (action) the skill produced."""
    end: int
    """One past the index of the last step it produced."""

    def __post_init__(self) -> None:
        if not 0 <= self.start <= self.end:
            raise ValueError(
                f"SkillLabel {self.operator}: expected 0 <= start <= end, got {self.start}, "
                f"{self.end}"
            )

    def to_dict(self) -> dict[str, Any]:
        return {
            "operator": self.operator,
            "objects": list(self.objects),
            "params": [float(p) for p in self.params],
            "start": self.start,
            "end": self.end,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SkillLabel:
        return cls(
            operator=str(data["operator"]),
            objects=tuple(str(o) for o in data["objects"]),
            params=tuple(float(p) for p in data["params"]),
            start=int(data["start"]),
            end=int(data["end"]),
        )


@dataclasses.dataclass
class EpisodeRecord:
    """One episode. ``T`` is the number of steps; arrays indexed by step have ``T`` rows, arrays
    indexed by time (observations, states) have ``T + 1`` (the reset observation first)."""

    env_id: str
    """The registered id, e.g. ``"kinder/Motion2D-p0-v0"``."""
    seed: int
    """The seed passed to ``reset``: replaying the actions from it reproduces the episode."""
    source: str
    """One of :data:`SOURCES`."""
    observations: FloatArray
    """``(T + 1, obs_dim)`` Box observations."""
    actions: FloatArray
    """``(T, act_dim)`` actions actually applied (clipped to the action bounds)."""
    rewards: FloatArray
    """``(T,)`` rewards."""
    terminated: bool
    """Whether the last step reached the goal."""
    truncated: bool
    """Whether the episode was cut by the time limit."""
    states: FloatArray | None = None
    """``(T + 1, state_dim)`` object-centric state vectors (the box space's vectorisation); equal
    to ``observations`` for envs without observation noise. ``None``: recover by replay."""
    step_seconds: FloatArray | None = None
    """``(T,)`` wall-clock seconds each step took to produce (agent plus env)."""
    skills: list[SkillLabel] = dataclasses.field(default_factory=list)
    """Skill labels, in step order, for skill-based sources."""
    task: str = ""
    """The env's natural-language goal."""
    versions: dict[str, str] = dataclasses.field(default_factory=package_versions)
    """Package versions that produced the episode."""
    metadata: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Anything else the source wants to keep (JSON-serialisable)."""

    def __post_init__(self) -> None:
        self.observations = np.asarray(self.observations, dtype=np.float64)
        self.actions = np.asarray(self.actions, dtype=np.float64)
        self.rewards = np.asarray(self.rewards, dtype=np.float64)
        steps = len(self.actions)
        if self.observations.ndim != 2 or len(self.observations) != steps + 1:
            raise ValueError(
                f"EpisodeRecord({self.env_id}, seed {self.seed}): expected {steps + 1} "
                f"observation rows for {steps} actions, got shape {self.observations.shape}"
            )
        if self.rewards.shape != (steps,):
            raise ValueError(
                f"EpisodeRecord({self.env_id}, seed {self.seed}): expected rewards of shape "
                f"({steps},), got {self.rewards.shape}"
            )
        if self.states is not None:
            self.states = np.asarray(self.states, dtype=np.float64)
            if len(self.states) != steps + 1:
                raise ValueError(
                    f"EpisodeRecord({self.env_id}, seed {self.seed}): expected {steps + 1} "
                    f"state rows, got {len(self.states)}"
                )
        if self.step_seconds is not None:
            self.step_seconds = np.asarray(self.step_seconds, dtype=np.float64)
        if self.source not in SOURCES:
            raise ValueError(f"Unknown source {self.source!r}; expected one of {SOURCES}")
        for label in self.skills:
            if label.end > steps:
                raise ValueError(
                    f"Skill {label.operator}{label.objects} covers steps up to {label.end}, but "
                    f"the episode has {steps}"
                )

    @property
    def num_steps(self) -> int:
        return len(self.actions)

    @property
    def success(self) -> bool:
        """Whether the episode reached the goal."""
        return self.terminated


class EpisodeRecorder:
    """Records one episode of a live env into an :class:`EpisodeRecord`.

    Use ``obs = recorder.reset(seed)``, then ``recorder.step(action)`` per step (it steps the env,
    clips the action as the env does and records what was applied), ``recorder.begin_skill(...)``
    / ``recorder.end_skill()`` around skill executions, and :meth:`finish`.

    Args:
        env: A registered id's env (the Box view; ``env.unwrapped`` is the object-centric env).
        env_id: The id the env was made from.
        source: One of :data:`SOURCES`.
    """

    def __init__(self, env: gymnasium.Env[Any, Any], env_id: str, source: str) -> None:
        if source not in SOURCES:
            raise ValueError(f"Unknown source {source!r}; expected one of {SOURCES}")
        self.env = env
        self.env_id = env_id
        self.source = source
        self._model = env.unwrapped
        if not isinstance(self._model, ObjectCentricEnv):
            raise TypeError(f"{env_id}: EpisodeRecorder needs a KinDER env (ObjectCentricEnv)")
        if not isinstance(env.action_space, spaces.Box):
            raise TypeError(f"{env_id}: EpisodeRecorder needs a Box action space")
        self._action_space: spaces.Box = env.action_space
        self._seed: int | None = None
        self.reset_info: dict[str, Any] = {}
        """The info dict of the latest :meth:`reset`."""

    def reset(self, seed: int) -> FloatArray:
        """Reset the env with ``seed`` and start a new record; returns the first observation
        (the reset's info dict is kept in :attr:`reset_info`)."""
        obs, info = self.env.reset(seed=seed)
        self.reset_info = dict(info)
        self._seed = seed
        self._observations = [np.asarray(obs, dtype=np.float64)]
        self._states = [self._state_vector()]
        self._actions: list[FloatArray] = []
        self._rewards: list[float] = []
        self._seconds: list[float] = []
        self._skills: list[SkillLabel] = []
        self._open_skill: tuple[str, tuple[str, ...], tuple[float, ...], int] | None = None
        self._terminated = False
        self._truncated = False
        self._last = time.perf_counter()
        return self._observations[0]

    def _state_vector(self) -> FloatArray:
        model = self._model
        assert isinstance(model, ObjectCentricEnv)
        return model.box_space.vectorize(model.get_state())

    def step(self, action: Any) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        """Apply ``action`` (clipped to the bounds) and record the step; returns ``env.step``'s
        result. ``step_seconds`` counts the time since the previous step or the reset."""
        if self._seed is None:
            raise RuntimeError("EpisodeRecorder.step called before reset")
        if self._terminated or self._truncated:
            raise RuntimeError("EpisodeRecorder.step called after the episode ended")
        space = self._action_space
        applied = np.clip(np.asarray(action, dtype=np.float64), space.low, space.high)
        obs, reward, terminated, truncated, info = self.env.step(applied)
        now = time.perf_counter()
        self._seconds.append(now - self._last)
        self._last = now
        self._actions.append(applied)
        self._rewards.append(float(reward))
        self._observations.append(np.asarray(obs, dtype=np.float64))
        self._states.append(self._state_vector())
        self._terminated, self._truncated = bool(terminated), bool(truncated)
        return self._observations[-1], float(reward), bool(terminated), bool(truncated), info

    def begin_skill(
        self, operator: str, objects: Sequence[str], params: Sequence[float] | FloatArray
    ) -> None:
        """Mark that the following steps come from this skill (closes any open skill)."""
        self.end_skill()
        self._open_skill = (
            operator,
            tuple(objects),
            tuple(float(p) for p in np.asarray(params, dtype=np.float64).ravel()),
            len(self._actions),
        )

    def end_skill(self) -> None:
        """Close the open skill label, if any."""
        if self._open_skill is not None:
            operator, objects, params, start = self._open_skill
            self._skills.append(SkillLabel(operator, objects, params, start, len(self._actions)))
            self._open_skill = None

    @property
    def done(self) -> bool:
        return self._terminated or self._truncated

    @property
    def num_steps(self) -> int:
        return len(self._actions)

    def finish(self, task: str = "", metadata: dict[str, Any] | None = None) -> EpisodeRecord:
        """The record of the episode so far."""
        if self._seed is None:
            raise RuntimeError("EpisodeRecorder.finish called before reset")
        self.end_skill()
        act_dim = self._action_space.shape[0]
        return EpisodeRecord(
            env_id=self.env_id,
            seed=self._seed,
            source=self.source,
            observations=np.stack(self._observations),
            actions=np.stack(self._actions) if self._actions else np.zeros((0, act_dim)),
            rewards=np.asarray(self._rewards, dtype=np.float64),
            terminated=self._terminated,
            truncated=self._truncated,
            states=np.stack(self._states),
            step_seconds=np.asarray(self._seconds, dtype=np.float64),
            skills=list(self._skills),
            task=task,
            metadata=dict(metadata or {}),
        )
