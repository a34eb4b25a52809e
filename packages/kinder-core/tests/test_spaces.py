import numpy as np
import pytest
from test_state import BASE, BLOCK, make_state

from kinder_core import ObjectCentricStateSpace, SpaceSampleError


def test_state_space_contains_and_sample_error() -> None:
    space = ObjectCentricStateSpace([BASE])
    s = make_state()
    assert space.contains(s)
    assert not space.contains(np.zeros(3))
    assert not ObjectCentricStateSpace([BLOCK]).contains(s)  # the robot is not a block
    bad = s.copy()
    bad.data[0] = np.nan
    assert not space.contains(bad)
    with pytest.raises(SpaceSampleError, match="reset"):
        space.sample()


def test_box_view_order_names_bounds_and_exact_inverse() -> None:
    s = make_state(11)
    robot = s.get_object_from_name("robot")
    order = [robot, *s.get_objects(BLOCK)]
    box = ObjectCentricStateSpace([BASE]).to_box(order, bounds={"x": (-5, 5), "robot.x": (0, 10)})
    assert box.shape == (3 + 11 * 4,)
    assert box.feature_names[:4] == ["robot.x", "robot.y", "robot.theta", "block0.x"]
    assert box.low[0] == 0 and box.high[3] == 5 and np.isinf(box.high[1])
    v = box.vectorize(s)
    assert v[0] == s.get(robot, "x") and v.dtype == np.float64
    back = box.devectorize(v)
    assert back == s
    np.testing.assert_array_equal(box.vectorize(back), v)
    table = box.markdown_table()
    assert "| 0 | robot | robot | x | 0 | 10 |" in table


def test_box_view_rejects_mismatched_inputs() -> None:
    s = make_state(2)
    box = ObjectCentricStateSpace([BASE]).to_box(list(s.objects))
    with pytest.raises(ValueError, match="expects 11"):
        box.devectorize(np.zeros(5))
    with pytest.raises(ValueError, match="do not match"):
        box.vectorize(make_state(3))
    with pytest.raises(ValueError, match="low > high"):
        ObjectCentricStateSpace([BASE]).to_box(list(s.objects), bounds={"x": (1, 0)})
    with pytest.raises(ValueError, match="not one of this space's types"):
        ObjectCentricStateSpace([BLOCK]).to_box(list(s.objects))
