"""Lifted STRIPS operators, their grounding, and PDDL export.

A :class:`LiftedOperator` has typed parameters (:class:`~kinder_gym.concepts.Variable` s),
preconditions, add effects and delete effects (lifted atoms over those parameters). Grounding it
on an object tuple gives a :class:`GroundOperator`, which applies to a set of ground atoms with the
usual STRIPS semantics: applicable when its preconditions hold; successor = (atoms − delete) ∪ add.

:func:`domain_to_pddl` and :func:`problem_to_pddl` write a domain and a problem as PDDL text (STRIPS
with typing), for external planners and for the prompts of the LLM/VLM planners.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

from kinder_core import Object, Type
from kinder_gym.concepts import (
    GroundAtom,
    LiftedAtom,
    Predicate,
    Variable,
    _check_pddl_name,
    object_combinations,
)


@dataclass(frozen=True, eq=False)
class LiftedOperator:
    """A STRIPS operator over typed parameters.

    Args:
        name: The operator's name (PDDL-safe).
        parameters: The typed variables; every atom below may mention only these.
        preconditions: Atoms that must hold for the operator to apply.
        add_effects: Atoms that hold afterwards.
        delete_effects: Atoms that no longer hold afterwards (unless also added).
    """

    name: str
    parameters: tuple[Variable, ...]
    preconditions: frozenset[LiftedAtom]
    add_effects: frozenset[LiftedAtom]
    delete_effects: frozenset[LiftedAtom] = frozenset()
    _grounded: dict[tuple[Object, ...], GroundOperator] = field(
        default_factory=dict, init=False, repr=False
    )

    def __post_init__(self) -> None:
        _check_pddl_name(self.name, "Operator name")
        object.__setattr__(self, "parameters", tuple(self.parameters))
        for attr in ("preconditions", "add_effects", "delete_effects"):
            object.__setattr__(self, attr, frozenset(getattr(self, attr)))
        names = [v.name for v in self.parameters]
        if len(set(names)) != len(names):
            raise ValueError(f"Operator {self.name}: repeated parameter names {names}")
        params = set(self.parameters)
        for attr in ("preconditions", "add_effects", "delete_effects"):
            for atom in getattr(self, attr):
                stray = [v for v in atom.variables if v not in params]
                if stray:
                    raise ValueError(
                        f"Operator {self.name}: {attr} atom {atom} uses {stray}, which are not "
                        f"parameters ({list(self.parameters)})"
                    )

    @property
    def types(self) -> tuple[Type, ...]:
        """The parameter types."""
        return tuple(v.type for v in self.parameters)

    def ground(self, objects: Sequence[Object]) -> GroundOperator:
        """The ground operator on ``objects`` (type-checked; memoised)."""
        key = tuple(objects)
        op = self._grounded.get(key)
        if op is None:
            if len(key) != len(self.parameters):
                raise ValueError(
                    f"Operator {self.name} takes {len(self.parameters)} object(s), got {key}"
                )
            for v, o in zip(self.parameters, key):
                if not o.type.is_subtype_of(v.type):
                    raise ValueError(
                        f"Operator {self.name}: {v.name} needs type {v.type.name!r}, got {o!r}"
                    )
            sub = dict(zip(self.parameters, key))
            op = GroundOperator(
                self,
                key,
                frozenset(a.ground(sub) for a in self.preconditions),
                frozenset(a.ground(sub) for a in self.add_effects),
                frozenset(a.ground(sub) for a in self.delete_effects),
            )
            self._grounded[key] = op
        return op

    def pddl_str(self) -> str:
        """The operator as a PDDL ``:action``."""
        params = " ".join(f"{v.name} - {v.type.name}" for v in self.parameters)
        pre = _conjunction(sorted(str(a) for a in self.preconditions))
        effects = sorted(str(a) for a in self.add_effects) + sorted(
            f"(not {a})" for a in self.delete_effects
        )
        return (
            f"  (:action {self.name}\n"
            f"    :parameters ({params})\n"
            f"    :precondition {pre}\n"
            f"    :effect {_conjunction(effects)})"
        )

    def __repr__(self) -> str:
        return f"{self.name}({', '.join(map(repr, self.parameters))})"

    def __hash__(self) -> int:
        return hash(self.name)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LiftedOperator):
            return NotImplemented
        return self is other or (
            self.name == other.name
            and self.parameters == other.parameters
            and self.preconditions == other.preconditions
            and self.add_effects == other.add_effects
            and self.delete_effects == other.delete_effects
        )


@dataclass(frozen=True, eq=False)
class GroundOperator:
    """A lifted operator applied to objects (see :meth:`LiftedOperator.ground`)."""

    parent: LiftedOperator
    objects: tuple[Object, ...]
    preconditions: frozenset[GroundAtom]
    add_effects: frozenset[GroundAtom]
    delete_effects: frozenset[GroundAtom]

    @cached_property
    def name(self) -> str:
        """``Op(obj1, obj2)``; unique per grounding."""
        return f"{self.parent.name}({', '.join(o.name for o in self.objects)})"

    def applicable(self, atoms: frozenset[GroundAtom] | set[GroundAtom]) -> bool:
        """Whether the preconditions hold in ``atoms``."""
        return self.preconditions <= atoms

    def apply(self, atoms: frozenset[GroundAtom]) -> frozenset[GroundAtom]:
        """The successor abstract state (no applicability check)."""
        return (atoms - self.delete_effects) | self.add_effects

    def pddl_str(self) -> str:
        """``(op obj1 obj2)``, the form a PDDL plan lists."""
        return "(" + " ".join([self.parent.name, *(o.name for o in self.objects)]) + ")"

    def __str__(self) -> str:
        return self.name

    def __repr__(self) -> str:
        return self.name

    def __hash__(self) -> int:
        return hash(self.name)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, GroundOperator):
            return NotImplemented
        return self.parent == other.parent and self.objects == other.objects

    def __lt__(self, other: GroundOperator) -> bool:
        return self.name < other.name


def ground_operators(
    operators: Iterable[LiftedOperator], objects: Iterable[Object], distinct: bool = True
) -> list[GroundOperator]:
    """Every type-consistent grounding of every operator over ``objects`` (deterministic order).

    With ``distinct`` (the default) no object fills two parameters of one grounding.
    """
    objs = sorted(set(objects), key=lambda o: o.name)
    out: list[GroundOperator] = []
    for op in sorted(operators, key=lambda o: o.name):
        out.extend(op.ground(c) for c in object_combinations(objs, op.types, distinct))
    return out


def _conjunction(items: Sequence[str]) -> str:
    if not items:
        return "()"
    return "(and " + " ".join(items) + ")"


def _type_closure(types: Iterable[Type]) -> list[Type]:
    seen: dict[str, Type] = {}
    for t in types:
        cur: Type | None = t
        while cur is not None:
            prev = seen.get(cur.name)
            if prev is not None and prev != cur:
                raise ValueError(f"Two different types are named {cur.name!r}")
            seen[cur.name] = cur
            cur = cur.parent
    return sorted(seen.values(), key=lambda t: t.name)


def domain_to_pddl(
    name: str,
    predicates: Iterable[Predicate],
    operators: Iterable[LiftedOperator],
    types: Iterable[Type] = (),
) -> str:
    """A PDDL domain (``:strips :typing``).

    Types are the given ones plus every type that a predicate or operator mentions, with their
    ancestors; a root type is declared a subtype of ``object``.
    """
    _check_pddl_name(name, "Domain name")
    preds = sorted(set(predicates), key=lambda p: p.name)
    ops = sorted(operators, key=lambda o: o.name)
    all_types = _type_closure(
        [*types, *(t for p in preds for t in p.types), *(t for o in ops for t in o.types)]
    )
    type_lines = " ".join(
        f"{t.name} - {t.parent.name if t.parent is not None else 'object'}" for t in all_types
    )
    pred_lines = "\n".join(f"    {p.pddl_signature()}" for p in preds)
    op_lines = "\n".join(o.pddl_str() for o in ops)
    return (
        f"(define (domain {name})\n"
        f"  (:requirements :strips :typing)\n"
        f"  (:types {type_lines})\n"
        f"  (:predicates\n{pred_lines}\n  )\n"
        f"{op_lines}\n"
        f")\n"
    )


def problem_to_pddl(
    domain_name: str,
    problem_name: str,
    objects: Iterable[Object],
    init_atoms: Iterable[GroundAtom],
    goal_atoms: Iterable[GroundAtom],
) -> str:
    """A PDDL problem: typed objects, the initial atoms and the goal conjunction."""
    _check_pddl_name(problem_name, "Problem name")
    objs = sorted(set(objects), key=lambda o: o.name)
    obj_lines = "\n".join(f"    {o.name} - {o.type.name}" for o in objs)
    init = "\n".join(f"    {a}" for a in sorted(set(init_atoms)))
    goal = _conjunction(sorted(str(a) for a in set(goal_atoms)))
    return (
        f"(define (problem {problem_name})\n"
        f"  (:domain {domain_name})\n"
        f"  (:objects\n{obj_lines}\n  )\n"
        f"  (:init\n{init}\n  )\n"
        f"  (:goal {goal})\n"
        f")\n"
    )
