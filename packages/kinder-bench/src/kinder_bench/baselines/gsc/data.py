"""GSC's training data: skill transitions ``(s, a, s′)`` with a success label.

The source is any skill-labelled :class:`~kinder_gym.demos.record.EpisodeRecord` s: a LeRobot
dataset (``kinder_gym.demos.lerobot_format.load_records``), a demo collection
(:mod:`kinder_bench.demos.collection`, whose bilevel-planner episodes label each plan step, a
ground skill and its parameters, with a :class:`~kinder_gym.demos.record.SkillLabel`), or records
built in memory.

:func:`transitions_from_records` turns every skill label into a :class:`SkillTransition` (the
state vectors at the skill's first and one-past-last step, and its parameters). Its label is the
*outcome*: 1 when the recorded end state's abstraction is the operator's predicted abstract
state (the bilevel planner's acceptance rule, :func:`abstract_match`), or the episode's goal was
reached there; 0 otherwise. :func:`perturbed_transitions` adds the feasibility classifier's
negatives (and more positives): from each recorded start state it executes perturbed parameters
with the skill's controller in the env model (``env.transition``) and labels the outcome the same
way; a controller that raises :class:`~kinder_gym.skills.SkillFailure` is a failure whose end state
is the start state.

States are the env's Box-view vectors (:attr:`ObjectCentricEnv.box_space`). A start state is
rebuilt with ``box_space.devectorize``, which drops any hidden simulator state (``sim_state``);
the dynamic families rebuild their simulator from the features, so the outcome of a perturbed
execution is that of the devectorized state.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv
from kinder_gym.demos.record import EpisodeRecord
from kinder_gym.model import PlanningModel, abstract_match
from kinder_gym.models import model_for
from kinder_gym.skills import GroundSkill, SkillFailure, execute_skill

FloatArray = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class SkillTransition:
    """One skill execution: ``operator(objects)`` with ``params`` took ``start`` to ``end``."""

    operator: str
    """The lifted operator's name (e.g. ``"PickStick"``)."""
    objects: tuple[str, ...]
    """The object names it was grounded on, in the operator's parameter order."""
    params: FloatArray
    start: FloatArray
    """The Box-view state vector at the skill's first step."""
    end: FloatArray
    """The Box-view state vector after the skill's last step."""
    success: bool
    """Whether the skill reached its operator's predicted abstract state (or the goal)."""


def lifted_name(operator: str) -> str:
    """``"Pick(robot, block)"`` → ``"Pick"``; a lifted name is returned unchanged."""
    return operator.split("(", 1)[0].strip()


def ground_skill(
    model: PlanningModel, state_objects: Sequence[Object], op: str, objects: Sequence[str]
) -> GroundSkill:
    """The ground skill ``op(objects)`` of ``model`` over the objects of a state."""
    by_name = {o.name: o for o in state_objects}
    missing = [n for n in objects if n not in by_name]
    if missing:
        raise ValueError(
            f"{model.name}: skill {op}{tuple(objects)} names objects {missing} that the state "
            f"does not have (its objects: {sorted(by_name)})"
        )
    skills = {s.name: s for s in model.skills}
    if op not in skills:
        raise ValueError(f"{model.name}: no skill for operator {op!r}; known: {sorted(skills)}")
    return skills[op].ground([by_name[n] for n in objects])


def skill_outcome(
    model: PlanningModel, gs: GroundSkill, start: FloatArray, end: FloatArray, terminated: bool
) -> bool:
    """Whether ``gs`` executed from ``start`` to ``end`` succeeded (see the module docstring)."""
    env = model.env
    if terminated:
        return True
    x0 = env.box_space.devectorize(start)
    x1 = env.box_space.devectorize(end)
    expected = gs.operator.apply(model.abstract(x0))
    return abstract_match(model, model.abstract(x1), expected)


def transitions_from_records(
    records: Sequence[EpisodeRecord], env: ObjectCentricEnv
) -> list[SkillTransition]:
    """Every skill label of ``records`` as a labelled transition (module docstring).

    Raises ``ValueError`` when a record is of another env, has no state vectors, or no record has
    skill labels.
    """
    model = model_for(env)
    env_id = env.spec.id if env.spec is not None else None
    objects = env.box_space.objects
    out: list[SkillTransition] = []
    for rec in records:
        if env_id is not None and rec.env_id != env_id:
            raise ValueError(
                f"Record of {rec.env_id} (seed {rec.seed}) given for {env_id}; train one env at "
                "a time"
            )
        if rec.states is None:
            raise ValueError(
                f"Record of {rec.env_id} (seed {rec.seed}) has no state vectors; GSC needs the "
                "object-centric states at skill boundaries"
            )
        for label in rec.skills:
            op = lifted_name(label.operator)
            gs = ground_skill(model, objects, op, label.objects)
            start, end = rec.states[label.start], rec.states[label.end]
            reached_goal = rec.terminated and label.end == rec.num_steps
            out.append(
                SkillTransition(
                    op,
                    tuple(label.objects),
                    np.asarray(label.params, dtype=np.float64),
                    start.copy(),
                    end.copy(),
                    skill_outcome(model, gs, start, end, reached_goal),
                )
            )
    if not out:
        raise ValueError("No skill labels in the records: GSC needs skill-labelled demonstrations")
    return out


def perturbed_transitions(
    env: ObjectCentricEnv,
    transitions: Sequence[SkillTransition],
    per_transition: int,
    noise: float,
    rng: np.random.Generator,
    uniform_fraction: float = 0.5,
    progress: Callable[[int], None] | None = None,
) -> list[SkillTransition]:
    """``per_transition`` executions per recorded successful transition with perturbed
    parameters, each labelled by its outcome (module docstring).

    A perturbation is a uniform draw from the controller's parameter space with probability
    ``uniform_fraction``, else the recorded parameters plus Gaussian noise of std
    ``noise × (high − low)``, clipped to the space. Parameterless skills are skipped.
    """
    model = model_for(env)
    objects = env.box_space.objects
    out: list[SkillTransition] = []
    for tr in transitions:
        if not tr.success or tr.params.size == 0:
            if progress is not None:
                progress(1)
            continue
        for _ in range(per_transition):
            gs = ground_skill(model, objects, tr.operator, tr.objects)
            space = gs.controller.params_space
            low, high = space.low.astype(np.float64), space.high.astype(np.float64)
            if rng.uniform() < uniform_fraction:
                params = rng.uniform(low, high)
            else:
                params = np.clip(
                    tr.params + rng.normal(0.0, noise, tr.params.shape) * (high - low), low, high
                )
            x0 = env.box_space.devectorize(tr.start)
            try:
                rollout = execute_skill(
                    gs.controller, x0, params, env.transition, model.max_skill_horizon
                )
            except SkillFailure:
                out.append(
                    SkillTransition(tr.operator, tr.objects, params, tr.start, tr.start, False)
                )
                continue
            end = env.box_space.vectorize(rollout.states[-1])
            ok = rollout.finished or rollout.terminated
            ok = ok and skill_outcome(model, gs, tr.start, end, rollout.terminated)
            out.append(SkillTransition(tr.operator, tr.objects, params, tr.start, end, ok))
        if progress is not None:
            progress(1)
    return out


def save_transitions(path: Path | str, transitions: Sequence[SkillTransition]) -> None:
    """Write transitions to an ``.npz`` file atomically (tmp file + ``os.replace``)."""
    if not transitions:
        raise ValueError("save_transitions: no transitions to save")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez(
        tmp,
        operator=np.asarray([t.operator for t in transitions], dtype=str),
        objects=np.asarray(["\t".join(t.objects) for t in transitions], dtype=str),
        success=np.asarray([t.success for t in transitions], dtype=bool),
        params=np.concatenate([t.params for t in transitions]),
        params_len=np.asarray([len(t.params) for t in transitions], dtype=np.int64),
        start=np.stack([t.start for t in transitions]),
        end=np.stack([t.end for t in transitions]),
    )
    os.replace(tmp, path)


def load_transitions(path: Path | str) -> list[SkillTransition]:
    """The transitions written by :func:`save_transitions`."""
    with np.load(Path(path), allow_pickle=False) as z:
        ends = np.cumsum(z["params_len"])
        params = np.split(np.asarray(z["params"], dtype=np.float64), ends[:-1])
        out = []
        for i in range(len(z["operator"])):
            objs = str(z["objects"][i])
            out.append(
                SkillTransition(
                    str(z["operator"][i]),
                    tuple(objs.split("\t")) if objs else (),
                    params[i],
                    np.asarray(z["start"][i], dtype=np.float64),
                    np.asarray(z["end"][i], dtype=np.float64),
                    bool(z["success"][i]),
                )
            )
    return out


__all__ = [
    "SkillTransition",
    "ground_skill",
    "lifted_name",
    "load_transitions",
    "perturbed_transitions",
    "save_transitions",
    "skill_outcome",
    "transitions_from_records",
]
