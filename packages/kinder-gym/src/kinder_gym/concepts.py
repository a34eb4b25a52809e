"""Concepts: typed predicates, atoms and the abstraction of a state into ground atoms.

A :class:`Predicate` is a name and a tuple of argument types, plus (optionally) a *classifier*: a
function of an object-centric state and an object tuple that says whether the atom holds. Calling a
predicate on objects gives a :class:`GroundAtom`; on :class:`Variable` s a :class:`LiftedAtom`.

:func:`abstract_state` evaluates every classifier on every type-consistent object tuple of a state
and returns the set of ground atoms that hold: the *abstract state*. Models whose atoms are cheaper
to compute together (one pass over the state) supply their own abstraction function instead.

Atoms compare, hash and sort by their PDDL text, e.g. ``(On block0 table)``, so sets of atoms are
deterministic across processes.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field

from kinder_core import Object, ObjectCentricState, Type

#: A classifier: does the predicate hold of these objects in this state?
Classifier = Callable[[ObjectCentricState, Sequence[Object]], bool]


@dataclass(frozen=True, order=True)
class Variable:
    """A typed variable for an object in a lifted atom or operator. Names start with ``?``."""

    name: str
    type: Type = field(compare=False)

    def __post_init__(self) -> None:
        if not self.name.startswith("?") or len(self.name) < 2:
            raise ValueError(f"Variable names start with '?' and are non-empty, got {self.name!r}")

    def __repr__(self) -> str:
        return f"{self.name}:{self.type.name}"


Entity = Object | Variable


def is_instance(entity: Entity, type_: Type) -> bool:
    """Whether an object or variable of ``entity``'s type may fill a slot of type ``type_``."""
    return entity.type.is_subtype_of(type_)


@dataclass(frozen=True)
class Predicate:
    """A typed predicate symbol with an optional classifier.

    Args:
        name: The predicate's name (PDDL-safe: letters, digits, ``_`` and ``-``).
        types: The argument types; an argument may be any object of that type or a subtype.
        classifier: ``classifier(state, objects) -> bool``; ``None`` for predicates whose atoms a
            model computes itself (see :func:`abstract_state`).
    """

    name: str
    types: tuple[Type, ...]
    classifier: Classifier | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "types", tuple(self.types))
        _check_pddl_name(self.name, "Predicate name")

    @property
    def arity(self) -> int:
        """The number of arguments."""
        return len(self.types)

    def __call__(self, entities: Sequence[Entity]) -> GroundAtom | LiftedAtom:
        """A ground atom (all objects) or a lifted atom (all variables)."""
        ents = tuple(entities)
        if ents and all(isinstance(e, Variable) for e in ents):
            return LiftedAtom(self, ents)  # type: ignore[arg-type]
        if all(isinstance(e, Object) for e in ents):
            return GroundAtom(self, ents)  # type: ignore[arg-type]
        raise ValueError(f"{self.name}: mix of objects and variables {ents}")

    def ground(self, objects: Sequence[Object]) -> GroundAtom:
        """The ground atom on ``objects``."""
        return GroundAtom(self, tuple(objects))

    def lift(self, variables: Sequence[Variable]) -> LiftedAtom:
        """The lifted atom on ``variables``."""
        return LiftedAtom(self, tuple(variables))

    def holds(self, state: ObjectCentricState, objects: Sequence[Object]) -> bool:
        """Evaluate the classifier (``ValueError`` if the predicate has none)."""
        if self.classifier is None:
            raise ValueError(f"Predicate {self.name} has no classifier")
        return bool(self.classifier(state, objects))

    def pddl_signature(self) -> str:
        """``(Name ?x0 - type0 ?x1 - type1)`` for a PDDL domain's ``:predicates``."""
        args = "".join(f" ?x{i} - {t.name}" for i, t in enumerate(self.types))
        return f"({self.name}{args})"

    def __repr__(self) -> str:
        return f"{self.name}({', '.join(t.name for t in self.types)})"


def _check_arguments(predicate: Predicate, entities: tuple[Entity, ...]) -> None:
    if len(entities) != predicate.arity:
        raise ValueError(
            f"{predicate.name} takes {predicate.arity} argument(s) "
            f"({[t.name for t in predicate.types]}), got {len(entities)}: {entities}"
        )
    for i, (e, t) in enumerate(zip(entities, predicate.types)):
        if not is_instance(e, t):
            raise ValueError(
                f"{predicate.name} argument {i} must be of type {t.name!r} (or a subtype), got "
                f"{e!r}"
            )


@dataclass(frozen=True, eq=False)
class _Atom:
    predicate: Predicate
    entities: tuple[Entity, ...]
    _str: str = field(init=False, repr=False)
    _hash: int = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "entities", tuple(self.entities))
        _check_arguments(self.predicate, self.entities)
        text = "(" + " ".join([self.predicate.name, *(e.name for e in self.entities)]) + ")"
        object.__setattr__(self, "_str", text)
        object.__setattr__(self, "_hash", hash((type(self).__name__, text)))

    def pddl_str(self) -> str:
        """The atom in PDDL syntax, e.g. ``(On block0 table)``."""
        return self._str

    def __str__(self) -> str:
        return self._str

    def __repr__(self) -> str:
        return self._str

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        assert isinstance(other, _Atom)
        return self._str == other._str

    def __lt__(self, other: _Atom) -> bool:
        return self._str < other._str


@dataclass(frozen=True, eq=False)
class GroundAtom(_Atom):
    """A predicate applied to objects."""

    entities: tuple[Object, ...]

    @property
    def objects(self) -> tuple[Object, ...]:
        """The atom's objects."""
        return self.entities

    def holds(self, state: ObjectCentricState) -> bool:
        """Evaluate the predicate's classifier on ``state``."""
        return self.predicate.holds(state, self.entities)

    def lift(self, substitution: dict[Object, Variable]) -> LiftedAtom:
        """The lifted atom with each object replaced by its variable."""
        return LiftedAtom(self.predicate, tuple(substitution[o] for o in self.entities))


@dataclass(frozen=True, eq=False)
class LiftedAtom(_Atom):
    """A predicate applied to variables."""

    entities: tuple[Variable, ...]

    @property
    def variables(self) -> tuple[Variable, ...]:
        """The atom's variables."""
        return self.entities

    def ground(self, substitution: dict[Variable, Object]) -> GroundAtom:
        """The ground atom with each variable replaced by its object."""
        try:
            return GroundAtom(self.predicate, tuple(substitution[v] for v in self.entities))
        except KeyError as e:
            raise ValueError(f"{self}: no object given for variable {e.args[0]!r}") from None


def object_combinations(
    objects: Iterable[Object], types: Sequence[Type], distinct: bool = True
) -> Iterator[tuple[Object, ...]]:
    """Every tuple of ``objects`` whose i-th entry is of ``types[i]`` (or a subtype).

    Objects are taken in name order, so the enumeration is deterministic. With ``distinct`` (the
    default) no object appears twice in a tuple.
    """
    ordered = sorted(set(objects), key=lambda o: o.name)
    choices = [[o for o in ordered if o.type.is_subtype_of(t)] for t in types]
    for combo in itertools.product(*choices):
        if distinct and len(set(combo)) < len(combo):
            continue
        yield combo


def abstract_state(
    state: ObjectCentricState,
    predicates: Iterable[Predicate],
    objects: Iterable[Object] | None = None,
) -> frozenset[GroundAtom]:
    """Every ground atom (of predicates with a classifier) that holds in ``state``.

    Args:
        state: The state to abstract.
        predicates: The predicates to evaluate; those without a classifier are skipped.
        objects: The objects to ground over (default: all of the state's objects).
    """
    objs = list(state.objects if objects is None else objects)
    atoms: set[GroundAtom] = set()
    for pred in predicates:
        if pred.classifier is None:
            continue
        for combo in object_combinations(objs, pred.types):
            if pred.classifier(state, combo):
                atoms.add(GroundAtom(pred, combo))
    return frozenset(atoms)


def sorted_atoms(atoms: Iterable[_Atom]) -> list[str]:
    """Atoms as sorted PDDL strings (handy for messages and tests)."""
    return sorted(str(a) for a in atoms)


def _check_pddl_name(name: str, what: str) -> None:
    if not name or not all(c.isalnum() or c in "_-" for c in name) or not name[0].isalpha():
        raise ValueError(
            f"{what} must start with a letter and contain only letters, digits, '_' or '-', "
            f"got {name!r}"
        )
