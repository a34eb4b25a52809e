"""Lifted operators: grounding, STRIPS semantics and PDDL export."""

from __future__ import annotations

import re

import pytest

from kinder_core import Object
from kinder_gym.concepts import Variable
from kinder_gym.operators import (
    LiftedOperator,
    domain_to_pddl,
    ground_operators,
    problem_to_pddl,
)
from kinder_gym.testing import (
    BLOCK,
    PICK,
    PLACE_IN,
    PLACE_OUT,
    REGION,
    ROBOT,
    TARGET_BLOCK,
    HandEmpty,
    Holding,
    InRegion,
    OutOfRegion,
    R,
)

robot = Object("robot", ROBOT)
target = Object("target", TARGET_BLOCK)
obstruction = Object("obstruction", BLOCK)
region = Object("region", REGION)


def _sexp(text: str) -> list[object]:
    """A minimal s-expression parser (checks that parentheses balance)."""
    tokens = re.findall(r"\(|\)|[^\s()]+", text)
    stack: list[list[object]] = [[]]
    for tok in tokens:
        if tok == "(":
            stack.append([])
        elif tok == ")":
            done = stack.pop()
            stack[-1].append(done)
        else:
            stack[-1].append(tok)
    assert len(stack) == 1, "unbalanced parentheses"
    return stack[0]


def test_grounding_is_typed_and_memoised() -> None:
    op = PICK.ground([robot, target])
    assert op is PICK.ground([robot, target])
    assert op.name == "Pick(robot, target)" and op.pddl_str() == "(Pick robot target)"
    assert op.preconditions == {HandEmpty.ground([robot])}
    assert op.add_effects == {Holding.ground([robot, target])}
    with pytest.raises(ValueError, match="needs type 'robot'"):
        PICK.ground([target, robot])
    with pytest.raises(ValueError, match="takes 2 object"):
        PICK.ground([robot])


def test_strips_semantics() -> None:
    atoms = frozenset({HandEmpty.ground([robot]), OutOfRegion.ground([target, region])})
    pick = PICK.ground([robot, target])
    assert pick.applicable(atoms)
    after = pick.apply(atoms)
    assert after == {Holding.ground([robot, target]), OutOfRegion.ground([target, region])}
    place = PLACE_IN.ground([robot, target, region])
    assert place.applicable(after) and not place.applicable(atoms)
    assert InRegion.ground([target, region]) in place.apply(after)


def test_ground_operators_enumerates_type_consistent_distinct_tuples() -> None:
    ops = ground_operators([PICK, PLACE_IN, PLACE_OUT], [robot, target, obstruction, region])
    names = [o.name for o in ops]
    assert names.count("Pick(robot, obstruction)") == 1
    assert "Pick(robot, target)" in names  # target_block is a subtype of block
    assert len(ops) == 2 + 2 + 2
    assert len(set(names)) == len(names)


def test_operator_validation() -> None:
    b = Variable("?b", BLOCK)
    with pytest.raises(ValueError, match="not parameters"):
        LiftedOperator("Bad", (R,), frozenset({Holding.lift([R, b])}), frozenset())
    with pytest.raises(ValueError, match="repeated parameter"):
        LiftedOperator("Bad", (R, R), frozenset(), frozenset())


def test_pddl_export_round_trips_structure() -> None:
    domain = domain_to_pddl(
        "toyplace",
        [HandEmpty, Holding, InRegion, OutOfRegion],
        [PICK, PLACE_IN, PLACE_OUT],
        types=[TARGET_BLOCK],
    )
    tree = _sexp(domain)
    assert tree[0][0:2] == ["define", ["domain", "toyplace"]]
    body = {item[0]: item for item in tree[0][2:]}
    assert body[":requirements"] == [":requirements", ":strips", ":typing"]
    types = body[":types"][1:]
    assert "target_block" in types and types[types.index("target_block") + 2] == "block"
    actions = [item for item in tree[0][2:] if item[0] == ":action"]
    assert [a[1] for a in actions] == ["Pick", "PlaceIn", "PlaceOut"]
    place_in = actions[1]
    assert place_in[place_in.index(":parameters") + 1] == [
        "?robot",
        "-",
        "robot",
        "?block",
        "-",
        "block",
        "?region",
        "-",
        "region",
    ]
    effect = place_in[place_in.index(":effect") + 1]
    assert ["not", ["Holding", "?robot", "?block"]] in effect
    problem = problem_to_pddl(
        "toyplace",
        "p1",
        [robot, target, obstruction, region],
        [HandEmpty.ground([robot]), InRegion.ground([obstruction, region])],
        [InRegion.ground([target, region])],
    )
    ptree = _sexp(problem)[0]
    parts = {item[0]: item for item in ptree[2:]}
    assert parts[":domain"] == [":domain", "toyplace"]
    assert parts[":objects"][1:4] == ["obstruction", "-", "block"]
    assert ["HandEmpty", "robot"] in parts[":init"]
    assert parts[":goal"] == [":goal", ["and", ["InRegion", "target", "region"]]]
