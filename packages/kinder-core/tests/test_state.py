import pickle
import subprocess
import sys

import numpy as np
import pytest

from kinder_core import Object, ObjectCentricState, StateLayout, Type

BASE = Type("base", ["x", "y"])
BLOCK = Type("block", ["width", "height"], parent=BASE)
ROBOT = Type("robot", ["theta"], parent=BASE)


def make_state(n: int = 3) -> ObjectCentricState:
    robot = Object("robot", ROBOT)
    blocks = [Object(f"block{i}", BLOCK) for i in range(n)]
    feats = {robot: {"x": 1.0, "y": 2.0, "theta": 0.5}}
    for i, b in enumerate(blocks):
        feats[b] = {"x": float(i), "y": -float(i), "width": 0.1 * (i + 1), "height": 0.2}
    return ObjectCentricState.from_features(feats)


def test_type_inherits_parent_features_first() -> None:
    assert BLOCK.features == ("x", "y", "width", "height")
    assert BLOCK.is_subtype_of(BASE) and not BASE.is_subtype_of(BLOCK)


def test_type_rejects_repeated_features() -> None:
    with pytest.raises(ValueError, match="repeats feature"):
        Type("bad", ["x"], parent=BASE)


def test_objects_sorted_by_name_lexicographically() -> None:
    s = make_state(12)
    names = [o.name for o in s.objects]
    assert names == sorted(names)
    assert names.index("block10") < names.index("block2")  # upstream's lexicographic order


def test_get_set_and_views() -> None:
    s = make_state()
    robot = s.get_object_from_name("robot")
    assert s.get(robot, "theta") == 0.5
    s.set(robot, "theta", 1.5)
    assert s.get(robot, "theta") == 1.5
    s[robot][0] = 9.0  # views write through
    assert s.get(robot, "x") == 9.0
    with pytest.raises(KeyError, match="no feature 'z'"):
        s.get(robot, "z")
    with pytest.raises(KeyError, match="No object named"):
        s.get_object_from_name("ghost")


def test_get_objects_includes_subtypes() -> None:
    s = make_state()
    assert len(s.get_objects(BASE)) == 4
    assert [o.name for o in s.get_objects(BLOCK)] == ["block0", "block1", "block2"]


def test_storage_is_one_contiguous_float64_array() -> None:
    s = make_state()
    assert s.data.dtype == np.float64 and s.data.flags["C_CONTIGUOUS"]
    assert s.data.shape == (3 * 4 + 3,)
    blocks = s.get_objects(BLOCK)
    idx = s.layout.indices(blocks, ["x", "width"])
    np.testing.assert_array_equal(s.data[idx], [[0, 0.1], [1, 0.2], [2, 0.30000000000000004]])


def test_copy_is_independent_and_shares_layout() -> None:
    s = make_state()
    c = s.copy()
    assert c == s and c.layout is s.layout
    c.data[0] += 1
    assert c != s


def test_allclose_and_equality() -> None:
    s = make_state()
    c = s.copy()
    c.data[0] += 1e-10
    assert c != s and c.allclose(s) and not c.allclose(s, atol=1e-12)
    assert not s.allclose(make_state(2))


def test_from_features_checks_completeness() -> None:
    with pytest.raises(ValueError, match="missing"):
        ObjectCentricState.from_features({Object("r", ROBOT): {"x": 1.0}})
    with pytest.raises(ValueError, match="unique"):
        StateLayout.of([Object("a", BASE), Object("a", BLOCK)])


def test_pickle_round_trip_interns_layout() -> None:
    s = make_state()
    s.sim_state = np.arange(3.0)
    t = pickle.loads(pickle.dumps(s))
    assert t == s and t.layout is s.layout
    np.testing.assert_array_equal(t.sim_state, [0, 1, 2])


def test_hash_matches_equality_and_is_stable_across_processes() -> None:
    s = make_state()
    c = s.copy()
    assert hash(s) == hash(c) and len({s, c}) == 1
    c.data[1] = -0.0 if c.data[1] == 0 else c.data[1]
    code = (
        f"import sys; sys.path.insert(0, {__file__.rsplit('/', 1)[0]!r}); "
        "from test_state import make_state; print(make_state().stable_hash())"
    )
    other = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert other == s.stable_hash()


def test_stable_hash_rounding_merges_near_duplicates() -> None:
    s = make_state()
    c = s.copy()
    c.data[0] += 1e-9
    assert c.stable_hash() != s.stable_hash()
    assert c.stable_hash(decimals=6) == s.stable_hash(decimals=6)


def test_pretty_lists_every_object_and_feature() -> None:
    text = make_state().pretty()
    assert "type: block" in text and "type: robot" in text
    assert "block2" in text and "theta" in text
