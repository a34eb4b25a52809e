"""Predicates, atoms and state abstraction on hand-built states."""

from __future__ import annotations

import pytest

from kinder_core import Object, ObjectCentricState, Type
from kinder_gym.concepts import (
    GroundAtom,
    LiftedAtom,
    Predicate,
    Variable,
    abstract_state,
    object_combinations,
)

THING = Type("thing", ["x"])
BLOCK = Type("block", ["w"], parent=THING)
TABLE = Type("table", ["top"])


def _state() -> tuple[ObjectCentricState, list[Object]]:
    a, b = Object("a", BLOCK), Object("b", BLOCK)
    t = Object("t", TABLE)
    state = ObjectCentricState.from_features(
        {a: {"x": 0.0, "w": 1.0}, b: {"x": 5.0, "w": 1.0}, t: {"top": 0.5}}
    )
    return state, [a, b, t]


def _left_of(s: ObjectCentricState, o: tuple[Object, ...] | list[Object]) -> bool:
    return s.get(o[0], "x") < s.get(o[1], "x")


LeftOf = Predicate("LeftOf", (THING, THING), _left_of)
Near = Predicate(
    "Near", (BLOCK, TABLE), lambda s, o: abs(s.get(o[0], "x") - s.get(o[1], "top")) < 1
)


def test_classifiers_on_hand_built_state() -> None:
    state, (a, b, t) = _state()
    assert LeftOf.holds(state, (a, b))
    assert not LeftOf.holds(state, (b, a))
    assert Near.holds(state, (a, t))
    assert not Near.holds(state, (b, t))
    atoms = abstract_state(state, [LeftOf, Near])
    assert {str(x) for x in atoms} == {"(LeftOf a b)", "(Near a t)"}


def test_atoms_are_typed_hashable_and_printable() -> None:
    _, (a, b, _t) = _state()
    atom = LeftOf([a, b])
    assert isinstance(atom, GroundAtom)
    assert atom == LeftOf.ground([a, b]) and hash(atom) == hash(LeftOf.ground([a, b]))
    assert atom.pddl_str() == "(LeftOf a b)"
    assert sorted([LeftOf([b, a]), atom]) == [atom, LeftOf([b, a])]
    with pytest.raises(ValueError, match="argument 1 must be of type 'table'"):
        Near([a, a])
    with pytest.raises(ValueError, match="takes 2 argument"):
        LeftOf([a])
    x = Variable("?x", BLOCK)
    lifted = LeftOf([x, Variable("?y", THING)])
    assert isinstance(lifted, LiftedAtom)
    assert lifted.ground({x: a, Variable("?y", THING): b}) == atom
    with pytest.raises(ValueError, match="no object given"):
        lifted.ground({x: a})
    with pytest.raises(ValueError, match="start with '\\?'"):
        Variable("x", BLOCK)
    with pytest.raises(ValueError, match="Predicate name"):
        Predicate("bad name", (BLOCK,))


def test_object_combinations_respect_types_and_distinctness() -> None:
    _, (a, b, t) = _state()
    combos = list(object_combinations([t, b, a], [THING, THING]))
    assert combos == [(a, b), (b, a)]  # subtypes count; no repeats; name order
    with_repeats = list(object_combinations([a, b], [BLOCK, BLOCK], distinct=False))
    assert len(with_repeats) == 4
    assert list(object_combinations([a, b, t], [TABLE])) == [(t,)]


def test_predicate_without_classifier_is_skipped_and_refuses_holds() -> None:
    state, (a, b, _) = _state()
    symbol = Predicate("Symbol", (BLOCK,))
    assert abstract_state(state, [symbol]) == frozenset()
    with pytest.raises(ValueError, match="no classifier"):
        symbol.holds(state, [a])
    assert abstract_state(state, [LeftOf], objects=[b]) == frozenset()
