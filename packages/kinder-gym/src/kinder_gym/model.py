"""The planning model of an environment: everything a bilevel planner needs besides the search.

A :class:`PlanningModel` bundles, for one env instance:

* the env itself (``env.transition(state, action)`` is the model of the dynamics: the env *is* the
  model, so plans refined on it replay exactly in the live episode),
* the types, predicates and the abstraction ``state -> set of ground atoms``,
* the goal atoms derived from a state,
* the skills (operator + controller pairs), from which the operators follow.

Models are made per env family by :func:`kinder_gym.models.create_model`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, Type
from kinder_gym.concepts import GroundAtom, Predicate, abstract_state
from kinder_gym.operators import (
    GroundOperator,
    LiftedOperator,
    domain_to_pddl,
    ground_operators,
    problem_to_pddl,
)
from kinder_gym.skills import GroundSkill, Skill

AbstractionFn = Callable[[ObjectCentricState], frozenset[GroundAtom]]


@dataclass
class PlanningModel:
    """Concepts, operators and skills of one env (see the module docstring).

    Args:
        name: The domain name (PDDL-safe), e.g. ``"motion2d"``.
        env: The object-centric env whose ``transition`` simulates the skills.
        types: The object types the domain talks about.
        predicates: The predicates of the abstraction.
        skills: One skill per operator.
        goal_fn: The goal atoms for the episode that starts in a state.
        abstraction_fn: ``state -> atoms``; default: every predicate's classifier on every
            type-consistent object tuple (:func:`~kinder_gym.concepts.abstract_state`).
        objects_fn: The objects operators are grounded over (default: all objects of the state).
        max_skill_horizon: The most env steps one skill execution may take.
        max_episode_steps: Step budget of an episode the planner should plan within (``None``:
            no limit beyond the planner's own).
        operator_filter: Optional ``(ground_operator, state) -> bool`` pruning groundings that can
            never apply in this episode (e.g. static geometry), applied once per episode.
        monotone_predicates: Names of predicates whose atoms, once true, stay true and are never
            harmful (e.g. a latching ``Pressed(button)``). A refinement step that makes such atoms
            true *in addition* to its operator's effects is accepted, and later steps whose effects
            already hold are skipped. Empty: exact abstract-state matching (upstream).
        monotone_negations: For monotone predicates that come with an explicit negation (e.g.
            ``NotObstructing`` and ``Obstructing``), ``{monotone name: negation name}``: when an
            extra monotone atom is accepted, its negation's atom over the same objects may vanish
            with it (a push that clears a second obstruction too).
    """

    name: str
    env: ObjectCentricEnv
    types: tuple[Type, ...]
    predicates: tuple[Predicate, ...]
    skills: tuple[Skill, ...]
    goal_fn: AbstractionFn
    abstraction_fn: AbstractionFn | None = None
    objects_fn: Callable[[ObjectCentricState], Sequence[Object]] | None = None
    max_skill_horizon: int = 100
    max_episode_steps: int | None = None
    operator_filter: Callable[[GroundOperator, ObjectCentricState], bool] | None = None
    monotone_predicates: frozenset[str] = frozenset()
    monotone_negations: Mapping[str, str] = field(default_factory=dict)
    _skill_by_op: dict[str, Skill] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        self.types = tuple(self.types)
        self.predicates = tuple(self.predicates)
        self.skills = tuple(self.skills)
        for s in self.skills:
            if s.operator.name in self._skill_by_op:
                raise ValueError(f"Model {self.name}: two skills for operator {s.operator.name}")
            self._skill_by_op[s.operator.name] = s
        known = {p.name for p in self.predicates}
        unknown = sorted(set(self.monotone_predicates) - known)
        if unknown:
            raise ValueError(f"Model {self.name}: unknown monotone predicates {unknown}")
        self.monotone_predicates = frozenset(self.monotone_predicates)
        for mono, neg in self.monotone_negations.items():
            if mono not in self.monotone_predicates or neg not in known:
                raise ValueError(
                    f"Model {self.name}: monotone_negations maps {mono!r} to {neg!r}; expected a "
                    "monotone predicate mapped to a predicate of the model"
                )
        for op in self.operators:
            for atom in op.preconditions | op.add_effects | op.delete_effects:
                if atom.predicate.name not in known:
                    raise ValueError(
                        f"Model {self.name}: operator {op.name} uses predicate "
                        f"{atom.predicate.name}, which is not in the model's predicates"
                    )

    @property
    def operators(self) -> tuple[LiftedOperator, ...]:
        """The skills' operators."""
        return tuple(s.operator for s in self.skills)

    def abstract(self, state: ObjectCentricState) -> frozenset[GroundAtom]:
        """The atoms that hold in ``state``."""
        if self.abstraction_fn is not None:
            return self.abstraction_fn(state)
        return abstract_state(state, self.predicates, self.objects(state))

    def goal(self, state: ObjectCentricState) -> frozenset[GroundAtom]:
        """The goal atoms of the episode starting in ``state``."""
        return self.goal_fn(state)

    def objects(self, state: ObjectCentricState) -> list[Object]:
        """The objects to ground operators over."""
        if self.objects_fn is not None:
            return sorted(self.objects_fn(state), key=lambda o: o.name)
        return list(state.objects)

    def ground_operators(self, state: ObjectCentricState) -> list[GroundOperator]:
        """Every grounding of every operator over :meth:`objects` (after ``operator_filter``)."""
        ops = ground_operators(self.operators, self.objects(state))
        if self.operator_filter is not None:
            keep = self.operator_filter
            ops = [o for o in ops if keep(o, state)]
        return ops

    def skill(self, operator: GroundOperator) -> GroundSkill:
        """The ground skill that implements a ground operator (a fresh controller)."""
        try:
            lifted = self._skill_by_op[operator.parent.name]
        except KeyError:
            raise KeyError(f"Model {self.name} has no skill for {operator.parent.name}") from None
        return lifted.ground(operator.objects)

    def domain_pddl(self) -> str:
        """The domain as PDDL."""
        return domain_to_pddl(self.name, self.predicates, self.operators, self.types)

    def problem_pddl(self, state: ObjectCentricState, problem_name: str = "episode") -> str:
        """The problem of the episode starting in ``state`` as PDDL."""
        return problem_to_pddl(
            self.name, problem_name, self.objects(state), self.abstract(state), self.goal(state)
        )


def abstract_match(
    model: PlanningModel, reached: frozenset[GroundAtom], expected: frozenset[GroundAtom]
) -> bool:
    """Whether a skill that was predicted to reach ``expected`` succeeded by reaching ``reached``:
    an exact match, or extra atoms of the model's monotone predicates only (each of which may
    take its declared negation's atom over the same objects with it). This is the acceptance
    rule of every planner over these models (bilevel planning, GSC, the skill probes)."""
    if reached == expected:
        return True
    monotone = model.monotone_predicates
    extra = reached - expected
    if not monotone or not all(a.predicate.name in monotone for a in extra):
        return False
    negations = model.monotone_negations
    may_vanish = {
        (negations[a.predicate.name], a.objects) for a in extra if a.predicate.name in negations
    }
    return all((a.predicate.name, a.objects) in may_vanish for a in expected - reached)
