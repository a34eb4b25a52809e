"""Skill-level control: one action = one parameterized skill run to its end.

Three pieces, shared by the foundation-model planners (LLMPlan, VLMPlan, LLMCon, VLMCon) and any
skill-level learner:

* :class:`SkillCall`: a skill by name, its objects by name and its continuous parameters, as a
  plan line names them (``RobotPress(robot:crv_robot, button0:circle)[0.5, 0.25]``).
* :func:`ground_call`: checks a call against a :class:`~kinder_gym.model.PlanningModel` and a state
  (known skill, known objects, arity, each object's type a subtype of the skill's parameter type,
  the number of parameters) and grounds it; parameters are clipped to the skill's
  ``params_space``. Bad calls raise :class:`InvalidSkillCall` naming what was wrong.
* :class:`SkillExecution`: a started ground skill that emits one env action per call, for agents
  driven one primitive step at a time (the benchmark runner). It follows
  :func:`~kinder_gym.skills.execute_skill` exactly (initiable check, ``reset``, then
  ``terminated`` / ``step`` / ``observe``, at most ``max_steps`` actions), so a plan refined by the
  bilevel planner replays action for action.
* :class:`SkillEnv`: a Gymnasium env over a KinDER env whose ``step`` takes a skill action and runs
  that skill on the wrapped env until the controller terminates, its step budget
  (``max_skill_steps``, default the model's ``max_skill_horizon``) is spent, the goal is reached
  or the wrapped env truncates. Its action space is a ``Dict`` of ``skill`` (index into
  :attr:`SkillEnv.skills`), ``objects`` (indices into :attr:`SkillEnv.objects`, padded to the
  largest arity; extra entries are ignored) and ``params`` (padded to the largest parameter count;
  each dimension bounded by the widest bounds over the skills, extra entries ignored); a
  :class:`SkillCall` is accepted too. The reward is the sum of the primitive rewards (−1 per
  step in KinDER). A skill that cannot be executed (invalid call, not initiable,
  :class:`~kinder_gym.skills.SkillFailure`) does not end the episode: the steps it took stay
  taken, and ``info["failure"]`` says why (``None`` otherwise).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, cast

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_gym.model import PlanningModel
from kinder_gym.skills import GroundSkill, Skill, SkillFailure

FloatArray = NDArray[np.float64]


class InvalidSkillCall(ValueError):
    """A skill call that does not fit the model or the state (unknown name, object, type, ...)."""


@dataclasses.dataclass(frozen=True)
class SkillCall:
    """A skill, its objects and its continuous parameters, by name (see the module docstring)."""

    skill: str
    objects: tuple[str, ...] = ()
    params: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "objects", tuple(self.objects))
        object.__setattr__(self, "params", tuple(float(p) for p in self.params))


def skills_by_name(model: PlanningModel) -> dict[str, Skill]:
    """The model's skills keyed by name (the operator's name)."""
    return {s.name: s for s in model.skills}


def ground_call(
    model: PlanningModel, state: ObjectCentricState, call: SkillCall
) -> tuple[GroundSkill, FloatArray]:
    """The ground skill (a fresh controller) and the clipped parameters of ``call`` in ``state``.

    Raises :class:`InvalidSkillCall` when the skill or an object is unknown, the arity or an
    object's type does not match, or the parameter count differs from ``params_space``.
    """
    skill = skills_by_name(model).get(call.skill)
    if skill is None:
        raise InvalidSkillCall(
            f"unknown skill {call.skill!r}; the skills of {model.name}: "
            f"{sorted(skills_by_name(model))}"
        )
    params_spec = skill.operator.parameters
    if len(call.objects) != len(params_spec):
        raise InvalidSkillCall(
            f"{call.skill} takes {len(params_spec)} object(s) "
            f"({', '.join(f'{v.name}:{v.type.name}' for v in params_spec)}), got "
            f"{len(call.objects)}: {list(call.objects)}"
        )
    by_name = {o.name: o for o in state.objects}
    objects: list[Object] = []
    for name, var in zip(call.objects, params_spec):
        obj = by_name.get(name)
        if obj is None:
            raise InvalidSkillCall(
                f"{call.skill}: unknown object {name!r}; the objects: {sorted(by_name)}"
            )
        if not obj.type.is_subtype_of(var.type):
            raise InvalidSkillCall(
                f"{call.skill}: {name} is a {obj.type.name}, but parameter {var.name} needs a "
                f"{var.type.name}"
            )
        objects.append(obj)
    box = skill.params_space
    if len(call.params) != box.shape[0]:
        raise InvalidSkillCall(
            f"{call.skill} takes {box.shape[0]} continuous parameter(s), got "
            f"{len(call.params)}: {list(call.params)}"
        )
    params = np.asarray(call.params, dtype=np.float64)
    if not np.all(np.isfinite(params)):
        raise InvalidSkillCall(f"{call.skill}: parameters must be finite, got {list(params)}")
    params = np.clip(params, box.low.astype(np.float64), box.high.astype(np.float64))
    return skill.ground(objects), params


class SkillExecution:
    """A ground skill started in a state, emitting one action per :meth:`next_action`.

    Args:
        ground: The ground skill (its controller is reset here).
        params: The continuous parameters.
        state: The state the skill starts in.
        max_steps: The most actions this execution emits.

    Raises :class:`~kinder_gym.skills.SkillFailure` if the skill is not initiable or its
    ``reset`` fails.
    """

    def __init__(
        self,
        ground: GroundSkill,
        params: FloatArray,
        state: ObjectCentricState,
        max_steps: int,
    ) -> None:
        if max_steps < 1:
            raise ValueError(f"max_steps must be >= 1, got {max_steps}")
        self.ground = ground
        self.max_steps = max_steps
        self.steps = 0
        controller = ground.controller
        if not controller.initiable(state):
            raise SkillFailure(f"{ground.name} is not initiable in this state")
        controller.reset(state, params)

    def observe(self, state: ObjectCentricState) -> None:
        """Feed the state reached after the last emitted action."""
        self.ground.controller.observe(state)

    def done(self) -> bool:
        """Whether the controller terminated or the step budget is spent."""
        return self.steps >= self.max_steps or self.ground.controller.terminated()

    @property
    def finished(self) -> bool:
        """Whether the controller itself said it is done."""
        return self.ground.controller.terminated()

    def next_action(self) -> FloatArray:
        """The next action (raises :class:`~kinder_gym.skills.SkillFailure` if the controller
        cannot continue, ``RuntimeError`` when already :meth:`done`)."""
        if self.done():
            raise RuntimeError(f"{self.ground.name}: next_action() after the execution is done")
        self.steps += 1
        return np.asarray(self.ground.controller.step(), dtype=np.float64)


def _state_of(env: gymnasium.Env[Any, Any]) -> ObjectCentricState:
    model = env.unwrapped
    if not isinstance(model, ObjectCentricEnv):
        raise TypeError(f"SkillEnv needs a KinDER env (ObjectCentricEnv), got {type(model)}")
    return model.get_state()


class SkillEnv(gymnasium.Env[Any, Any]):
    """A skill-level Gymnasium env over a KinDER env (see the module docstring).

    Args:
        env: A KinDER env: a registered id's Box view (``kinder_core.make``) or an
            :class:`~kinder_core.ObjectCentricEnv`. Observations are the wrapped env's.
        model: The planning model whose skills are the actions; default: the env family's model
            (:func:`kinder_gym.models.create_model`).
        max_skill_steps: The most primitive steps one skill action runs; default: the model's
            ``max_skill_horizon``.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"]}  # noqa: RUF012

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        model: PlanningModel | None = None,
        max_skill_steps: int | None = None,
    ) -> None:
        oc = env.unwrapped
        if not isinstance(oc, ObjectCentricEnv):
            raise TypeError(f"SkillEnv needs a KinDER env (ObjectCentricEnv), got {type(oc)}")
        if model is None:
            from kinder_gym.models import create_model

            model = create_model(oc)
        if max_skill_steps is not None and max_skill_steps < 1:
            raise ValueError(f"max_skill_steps must be >= 1, got {max_skill_steps}")
        self.env = env
        self.model = model
        self.max_skill_steps = max_skill_steps or model.max_skill_horizon
        self.render_mode = env.render_mode
        self.skills: tuple[Skill, ...] = tuple(model.skills)
        self.objects: tuple[Object, ...] = tuple(oc.exemplar_state().objects)
        self.observation_space = env.observation_space
        arity = max((len(s.operator.parameters) for s in self.skills), default=0)
        dims = max((s.params_space.shape[0] for s in self.skills), default=0)
        low = np.zeros(dims)
        high = np.zeros(dims)
        for d in range(dims):
            lows = [
                float(s.params_space.low[d]) for s in self.skills if s.params_space.shape[0] > d
            ]
            highs = [
                float(s.params_space.high[d]) for s in self.skills if s.params_space.shape[0] > d
            ]
            low[d], high[d] = min(lows), max(highs)
        self.action_space = spaces.Dict(
            {
                "skill": spaces.Discrete(len(self.skills)),
                "objects": spaces.MultiDiscrete([max(len(self.objects), 1)] * arity),
                "params": spaces.Box(low, high, (dims,), dtype=np.float64),
            }
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.objects = tuple(_state_of(self.env).objects)
        return obs, info

    def to_call(self, action: SkillCall | Mapping[str, Any]) -> SkillCall:
        """A :class:`SkillCall` from an action of :attr:`action_space` (or a call itself)."""
        if isinstance(action, SkillCall):
            return action
        try:
            k = int(action["skill"])
            obj_idx = [int(i) for i in np.asarray(action.get("objects", ()), dtype=np.int64)]
            params = np.asarray(action.get("params", ()), dtype=np.float64).reshape(-1)
        except (KeyError, TypeError, ValueError) as e:
            raise InvalidSkillCall(
                f"a skill action is a SkillCall or a mapping with 'skill', 'objects' and 'params' "
                f"({self.action_space}); got {action!r} ({e})"
            ) from None
        if not 0 <= k < len(self.skills):
            raise InvalidSkillCall(f"skill index {k} out of range [0, {len(self.skills)})")
        skill = self.skills[k]
        n_obj, n_par = len(skill.operator.parameters), skill.params_space.shape[0]
        if len(obj_idx) < n_obj or any(not 0 <= i < len(self.objects) for i in obj_idx[:n_obj]):
            raise InvalidSkillCall(
                f"{skill.name} needs {n_obj} object indices in [0, {len(self.objects)}), got "
                f"{obj_idx}"
            )
        if params.shape[0] < n_par:
            raise InvalidSkillCall(
                f"{skill.name} needs {n_par} parameters, got {params.shape[0]}: {list(params)}"
            )
        return SkillCall(
            skill.name,
            tuple(self.objects[i].name for i in obj_idx[:n_obj]),
            tuple(float(p) for p in params[:n_par]),
        )

    def step(self, action: SkillCall | Mapping[str, Any]) -> tuple[Any, float, bool, bool, Any]:
        call = self.to_call(action)
        state = _state_of(self.env)
        info: dict[str, Any] = {"skill": call, "steps": 0, "finished": False, "failure": None}
        reward, terminated, truncated = 0.0, False, False
        obs: Any = None
        try:
            ground, params = ground_call(self.model, state, call)
            execution = SkillExecution(ground, params, state, self.max_skill_steps)
            while not execution.done():
                obs, r, terminated, truncated, step_info = self.env.step(execution.next_action())
                reward += float(r)
                info["steps"] += 1
                info["env_info"] = step_info
                if terminated or truncated:
                    break
                execution.observe(_state_of(self.env))
            info["finished"] = execution.finished
        except (InvalidSkillCall, SkillFailure) as e:
            info["failure"] = f"{type(e).__name__}: {e}"
        if obs is None:  # no primitive step was taken: observe the unchanged state
            obs = self._observe()
        return obs, reward, terminated, truncated, info

    def _observe(self) -> Any:
        oc = cast(ObjectCentricEnv, self.env.unwrapped)
        state = oc.get_state()
        if isinstance(self.env.observation_space, spaces.Box):
            return oc.box_space.vectorize(state)
        return state

    def render(self) -> Any:
        return self.env.render()


def run_plan(env: SkillEnv, calls: Sequence[SkillCall]) -> tuple[bool, int, list[dict[str, Any]]]:
    """Run ``calls`` on ``env`` (already reset) until the goal, a failure or truncation:
    ``(goal reached, primitive steps, per-call infos)``."""
    steps, infos = 0, []
    for call in calls:
        _, _, terminated, truncated, info = env.step(call)
        steps += int(info["steps"])
        infos.append(info)
        if terminated:
            return True, steps, infos
        if truncated or info["failure"] is not None:
            break
    return False, steps, infos


__all__ = [
    "InvalidSkillCall",
    "SkillCall",
    "SkillEnv",
    "SkillExecution",
    "ground_call",
    "run_plan",
    "skills_by_name",
]
