"""The hand's operators, shared by the planning models of every robot kind.

A model's hand has ``HandEmpty(robot)`` and ``Holding(robot, item)`` predicates (each robot base
builds them for its robot type); picking and placing change them the same way in every family,
whatever else (the source or target of the item) they need and change. The robot's moves that
need the hand empty and leave it so (a push, a press, opening a drawer) are
:func:`empty_hand_operator`; those that use a held tool and keep holding it (a hook, a stick, a
scoop, a wiper) are :func:`tool_operator`. A model whose goal is one classified atom (the robot
at a target, a block at its goal pose) pairs it with its negation (:func:`goal_predicates`) and
reaches it with one move that turns the one into the other (:func:`goal_operator`);
:func:`first_objects_goal` is the goal of a model with one robot and one target.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from kinder_core import ObjectCentricState, Type
from kinder_gym.concepts import Classifier, GroundAtom, LiftedAtom, Predicate, Variable
from kinder_gym.operators import LiftedOperator


def pick_operator(
    name: str,
    hand_empty: Predicate,
    holding: Predicate,
    item: Variable,
    source: Sequence[LiftedAtom],
    also_add: Sequence[LiftedAtom] = (),
    params: Sequence[Variable] = (),
    delete_source: bool = True,
    also_need: Sequence[LiftedAtom] = (),
) -> LiftedOperator:
    """``name(?robot, item, *params)``, ``?robot`` of ``hand_empty``'s type: with the hand empty
    and ``source`` (and ``also_need``) true, hold ``item`` (and make ``also_add`` true); the hand
    being empty and (unless not ``delete_source``) ``source`` are deleted."""
    r = Variable("?robot", hand_empty.types[0])
    before = frozenset({hand_empty.lift([r]), *source})
    delete = before if delete_source else frozenset({hand_empty.lift([r])})
    add = frozenset({holding.lift([r, item]), *also_add})
    return LiftedOperator(name, (r, item, *params), before | frozenset(also_need), add, delete)


def place_operator(
    name: str,
    hand_empty: Predicate,
    holding: Predicate,
    item: Variable,
    target: Sequence[LiftedAtom],
    also_need: Sequence[LiftedAtom] = (),
    params: Sequence[Variable] = (),
    also_delete: Sequence[LiftedAtom] = (),
) -> LiftedOperator:
    """``name(?robot, item, *params)``: holding ``item`` (and with ``also_need`` true), let go
    of it so that ``target`` holds; the hand is empty again and ``Holding`` (and ``also_delete``)
    are deleted."""
    r = Variable("?robot", hand_empty.types[0])
    held = holding.lift([r, item])
    return LiftedOperator(
        name,
        (r, item, *params),
        frozenset({held, *also_need}),
        frozenset({hand_empty.lift([r]), *target}),
        frozenset({held, *also_delete}),
    )


def empty_hand_operator(
    name: str,
    hand_empty: Predicate,
    params: Sequence[Variable],
    pre: Sequence[LiftedAtom],
    add: Sequence[LiftedAtom],
    delete: Sequence[LiftedAtom] = (),
) -> LiftedOperator:
    """``name(?robot, *params)``, ``?robot`` of ``hand_empty``'s type: with the hand empty and
    ``pre`` true, the robot itself makes ``add`` true and ``delete`` false; the hand stays
    empty."""
    r = Variable("?robot", hand_empty.types[0])
    return LiftedOperator(
        name,
        (r, *params),
        frozenset({hand_empty.lift([r]), *pre}),
        frozenset(add),
        frozenset(delete),
    )


def tool_operator(
    name: str,
    holding: Predicate,
    tool: Variable,
    params: Sequence[Variable],
    pre: Sequence[LiftedAtom],
    add: Sequence[LiftedAtom],
    delete: Sequence[LiftedAtom] = (),
) -> LiftedOperator:
    """``name(?robot, tool, *params)``, ``?robot`` of ``holding``'s first type: holding ``tool``
    and with ``pre`` true, the robot uses the tool to make ``add`` true and ``delete`` false; it
    keeps holding the tool."""
    r = Variable("?robot", holding.types[0])
    return LiftedOperator(
        name,
        (r, tool, *params),
        frozenset({holding.lift([r, tool]), *pre}),
        frozenset(add),
        frozenset(delete),
    )


def goal_predicates(
    name: str, types: Sequence[Type], holds: Classifier
) -> tuple[Predicate, Predicate]:
    """``name`` classified by ``holds`` and ``Not<name>``, its negation."""
    return (
        Predicate(name, tuple(types), holds),
        Predicate(f"Not{name}", tuple(types), lambda s, o: not holds(s, o)),
    )


def first_objects_goal(
    goal: Predicate,
) -> Callable[[ObjectCentricState], frozenset[GroundAtom]]:
    """The goal function ``{goal(o1, …, on)}``, each ``oi`` the state's first object of
    ``goal``'s i-th type (a model of one robot and one target)."""

    def goal_fn(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({goal.ground([state.get_objects(t)[0] for t in goal.types])})

    return goal_fn


def goal_operator(
    name: str,
    params: Sequence[Variable],
    goal: Predicate,
    not_goal: Predicate,
    args: Sequence[Variable],
) -> LiftedOperator:
    """``name(*params)``: with ``not_goal(*args)`` true, make ``goal(*args)`` true instead."""
    before = frozenset({not_goal.lift(args)})
    return LiftedOperator(name, tuple(params), before, frozenset({goal.lift(args)}), before)


__all__: Sequence[str] = [
    "empty_hand_operator",
    "first_objects_goal",
    "goal_operator",
    "goal_predicates",
    "pick_operator",
    "place_operator",
    "tool_operator",
]
