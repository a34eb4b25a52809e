"""Tests of the vectorized 2D geometry kernels against brute-force point sampling."""

import numpy as np
import pytest

from kinder_garden2d.geometry import (
    circle_circle_overlap,
    circle_push_out_of_obb,
    lshape_obbs,
    obb_circle_overlap,
    obb_corners,
    obb_obb_overlap,
    obbs_from_anchor,
    points_in_obbs,
    wrap_angle,
)


def random_obbs(rng: np.random.Generator, n: int) -> np.ndarray:
    return obbs_from_anchor(
        rng.uniform(0, 1, n),
        rng.uniform(0, 1, n),
        rng.uniform(-np.pi, np.pi, n),
        rng.uniform(0.05, 0.4, n),
        rng.uniform(0.05, 0.4, n),
    )


def sample_points(obb: np.ndarray, k: int = 40) -> np.ndarray:
    """A dense grid of points filling the box."""
    cx, cy, c, s, hw, hh = obb
    u, v = np.meshgrid(np.linspace(-hw, hw, k), np.linspace(-hh, hh, k))
    return np.stack([cx + c * u - s * v, cy + s * u + c * v], axis=-1).reshape(-1, 2)


def test_obbs_from_anchor_rotates_about_the_bottom_left_corner() -> None:
    corners = obb_corners(obbs_from_anchor(1.0, 2.0, np.pi / 2, 3.0, 1.0))[0]
    np.testing.assert_allclose(corners, [[1, 2], [1, 5], [0, 5], [0, 2]], atol=1e-12)


def test_obb_overlap_agrees_with_sampling() -> None:
    rng = np.random.default_rng(0)
    a, b = random_obbs(rng, 30), random_obbs(rng, 30)
    got = obb_obb_overlap(a, b)
    assert got.shape == (30, 30)
    for i in range(30):
        pts = sample_points(a[i])
        sampled = points_in_obbs(pts, b).any(axis=0)
        # Sampling finds every overlap except grazing ones thinner than the grid.
        assert np.all(got[i] | ~sampled)
    assert 0 < got.sum() < got.size
    np.testing.assert_array_equal(got, obb_obb_overlap(b, a).T)


def test_obb_circle_overlap_agrees_with_sampling() -> None:
    rng = np.random.default_rng(1)
    a = random_obbs(rng, 20)
    circles = np.column_stack(
        [rng.uniform(0, 1, 25), rng.uniform(0, 1, 25), rng.uniform(0.02, 0.2, 25)]
    )
    got = obb_circle_overlap(a, circles)
    for i in range(20):
        pts = sample_points(a[i], 60)
        d = np.linalg.norm(pts[:, None, :] - circles[None, :, :2], axis=2)
        sampled = (d <= circles[:, 2]).any(axis=0)
        assert np.all(got[i] | ~sampled)
        # Distance from the circle centres to the box never exceeds the radius when overlapping.
        near = d.min(axis=0) <= circles[:, 2] - 0.02
        assert np.all(got[i][near])
    assert 0 < got.sum() < got.size


def test_touching_counts_as_overlap() -> None:
    a = obbs_from_anchor(0.0, 0.0, 0.0, 1.0, 1.0)
    b = obbs_from_anchor(1.0, 0.0, 0.0, 1.0, 1.0)
    c = obbs_from_anchor(1.0 + 1e-9, 0.0, 0.0, 1.0, 1.0)
    assert obb_obb_overlap(a, b)[0, 0] and not obb_obb_overlap(a, c)[0, 0]
    assert obb_circle_overlap(a, np.array([[1.5, 0.5, 0.5]]))[0, 0]
    assert not obb_circle_overlap(a, np.array([[1.5, 0.5, 0.4999]]))[0, 0]
    assert circle_circle_overlap(np.array([[0, 0, 1.0]]), np.array([[2.0, 0, 1.0]]))[0, 0]
    assert not circle_circle_overlap(np.array([[0, 0, 1.0]]), np.array([[2.1, 0, 1.0]]))[0, 0]


def test_corner_circle_is_not_fooled_by_the_bounding_box() -> None:
    box = obbs_from_anchor(0.0, 0.0, 0.0, 1.0, 1.0)
    # Inside the box's AABB grown by r, but farther than r from the corner.
    assert not obb_circle_overlap(box, np.array([[1.08, 1.08, 0.1]]))[0, 0]
    assert obb_circle_overlap(box, np.array([[1.07, 1.07, 0.1]]))[0, 0]


def test_lshape_arms() -> None:
    boxes = lshape_obbs(0.0, 0.0, 0.0, 0.1, 2.0, 1.0)
    corners = obb_corners(boxes)
    np.testing.assert_allclose(corners[0].min(axis=0), [-2.0, -0.1])
    np.testing.assert_allclose(corners[0].max(axis=0), [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(corners[1].min(axis=0), [-0.1, -1.0])
    rotated = obb_corners(lshape_obbs(1.0, 1.0, np.pi / 2, 0.1, 2.0, 1.0))
    # Turned by 90°: the long arm hangs down from the anchor.
    np.testing.assert_allclose(rotated[0].min(axis=0), [1.0, -1.0], atol=1e-12)


@pytest.mark.parametrize("local", [(1.05, 0.5), (0.5, 0.92), (0.97, 0.95), (1.03, 1.04)])
def test_push_out_separates_with_the_smallest_move(local: tuple[float, float]) -> None:
    th = 0.3
    box = obbs_from_anchor(0.0, 0.0, th, 1.0, 1.0)[0]
    c, s = np.cos(th), np.sin(th)
    center = (c * local[0] - s * local[1], s * local[0] + c * local[1])  # in the box's frame
    circle = np.array([*center, 0.1])
    assert obb_circle_overlap(box[None], circle[None])[0, 0]
    move = circle_push_out_of_obb(box, circle)
    moved = circle + np.array([*move, 0.0])
    shrink, grow = np.array([0.0, 0.0, -1e-9]), np.array([0.0, 0.0, 1e-6])
    assert not obb_circle_overlap(box[None], (moved + shrink)[None])[0, 0]
    # Nearly touching afterwards: not pushed farther than needed.
    assert obb_circle_overlap(box[None], (moved + grow)[None])[0, 0]


def test_push_out_is_zero_when_apart() -> None:
    box = obbs_from_anchor(0.0, 0.0, 0.0, 1.0, 1.0)[0]
    assert np.all(circle_push_out_of_obb(box, np.array([2.0, 2.0, 0.1])) == 0)


def test_wrap_angle() -> None:
    np.testing.assert_allclose(
        wrap_angle([0.0, np.pi, -np.pi, 3 * np.pi / 2]), [0, -np.pi, -np.pi, -np.pi / 2]
    )
