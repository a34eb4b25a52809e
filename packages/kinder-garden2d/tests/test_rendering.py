"""Tests of the numpy rasterizer: geometry, coverage (antialiasing), alpha blending, bounds."""

import numpy as np
import pytest

from kinder_garden2d.rendering import Canvas, rectangle_vertices

WHITE = (255, 255, 255)
BLACK = (0, 0, 0)


def unit_canvas(supersample: int = 4) -> Canvas:
    """10×10 pixels over [0, 10]², so one world unit is one pixel."""
    return Canvas((0.0, 10.0, 0.0, 10.0), 10, background=WHITE, supersample=supersample)


def test_size_from_aspect_ratio_and_fresh_image() -> None:
    canvas = Canvas((0.0, 3.5, 0.0, 2.5), 700)
    img = canvas.image()
    assert img.shape == (500, 700, 3) and img.dtype == np.uint8
    assert np.all(img == 255)
    img[:] = 0  # the caller owns the returned array
    assert np.all(canvas.image() == 255)


def test_rectangle_vertices_rotate_about_the_anchor() -> None:
    v = rectangle_vertices(1.0, 2.0, 3.0, 1.0, np.pi / 2)
    np.testing.assert_allclose(v, [[1, 2], [1, 5], [0, 5], [0, 2]], atol=1e-12)
    np.testing.assert_allclose(
        rectangle_vertices(0.0, 0.0, 2.0, 1.0, 0.0), [[0, 0], [2, 0], [2, 1], [0, 1]]
    )


def test_y_axis_points_up() -> None:
    canvas = unit_canvas()
    canvas.polygon(rectangle_vertices(0, 9, 10, 1, 0), BLACK)  # the top row of the world
    img = canvas.image()
    assert np.all(img[0] == 0) and np.all(img[1:] == 255)


def test_pixel_aligned_edges_are_crisp_and_half_pixels_are_blended() -> None:
    canvas = unit_canvas(supersample=4)
    canvas.polygon(rectangle_vertices(0, 0, 2.5, 10, 0), BLACK)
    row = canvas.image()[5, :, 0].astype(int)
    assert list(row[:2]) == [0, 0]
    assert row[2] == 128  # half covered: halfway between black and white
    assert np.all(row[3:] == 255)


def test_supersample_one_disables_antialiasing() -> None:
    canvas = unit_canvas(supersample=1)
    canvas.circle((5.0, 5.0), 3.3, BLACK)
    values = np.unique(canvas.image())
    assert set(values.tolist()) == {0, 255}


def test_circle_coverage_matches_its_area() -> None:
    canvas = Canvas((0.0, 1.0, 0.0, 1.0), 200, supersample=4)
    r = 0.3
    canvas.circle((0.5, 0.5), r, BLACK)
    img = canvas.image()[..., 0].astype(float)
    covered_area = np.sum(1.0 - img / 255.0) / 200**2
    assert covered_area == pytest.approx(np.pi * r * r, rel=2e-3)
    # Antialiased: the rim has intermediate values.
    assert np.any((img > 10) & (img < 245))


def test_rotated_polygon_coverage_matches_its_area() -> None:
    canvas = Canvas((0.0, 1.0, 0.0, 1.0), 300, supersample=3)
    canvas.polygon(rectangle_vertices(0.4, 0.1, 0.3, 0.5, 0.7), BLACK)
    covered = np.sum(1.0 - canvas.image()[..., 0] / 255.0) / 300**2
    assert covered == pytest.approx(0.15, rel=5e-3)


def test_vertex_order_does_not_matter() -> None:
    v = rectangle_vertices(2.1, 3.3, 4.2, 2.7, 0.4)
    a, b = unit_canvas(), unit_canvas()
    a.polygon(v, (10, 200, 30))
    b.polygon(v[::-1], (10, 200, 30))
    assert np.array_equal(a.image(), b.image())


def test_non_convex_polygon_leaves_its_notch_empty() -> None:
    canvas = Canvas((0.0, 4.0, 0.0, 4.0), 40)
    l_shape = [(0, 0), (4, 0), (4, 1), (1, 1), (1, 4), (0, 4)]
    canvas.polygon(l_shape, BLACK)
    img = canvas.image()[..., 0]
    assert img[35, 30] == 0  # in the horizontal leg (y≈0.45, x≈3.05)
    assert img[5, 5] == 0  # in the vertical leg
    assert img[10, 30] == 255  # in the notch
    assert np.sum(1.0 - img / 255.0) / 100 == pytest.approx(7.0, rel=1e-6)


def test_alpha_blending_composes_in_order() -> None:
    canvas = unit_canvas()
    canvas.polygon(rectangle_vertices(0, 0, 10, 10, 0), (255, 0, 0), alpha=0.5)
    assert tuple(canvas.image()[5, 5]) == (255, 128, 128)
    canvas.polygon(rectangle_vertices(0, 0, 10, 10, 0), (0, 0, 255), alpha=0.5)
    # 0.5 blue over (255, 128, 128) (the canvas keeps 8 bits per channel)
    assert tuple(canvas.image()[5, 5]) == (128, 64, 192)
    canvas.polygon(rectangle_vertices(0, 0, 10, 10, 0), BLACK, alpha=0.0)
    assert tuple(canvas.image()[5, 5]) == (128, 64, 192)


def test_outline_is_a_band_inside_the_boundary() -> None:
    canvas = Canvas((0.0, 1.0, 0.0, 1.0), 100)
    canvas.circle((0.5, 0.5), 0.3, (200, 200, 200), outline=BLACK, outline_width=0.04)
    img = canvas.image()[..., 0]
    assert img[50, 50] == 200  # centre keeps the fill
    assert img[50, 78] == 0  # in the band (x = 0.785, 0.285 from the centre)
    assert img[50, 82] == 255  # just outside the rim (x = 0.825)
    covered = np.sum(255 - img) / 255 / 100**2
    # The outline replaces part of the fill; the disc's total coverage is unchanged.
    ring = np.pi * (0.3**2 - 0.26**2)
    expected = ring + (np.pi * 0.26**2) * (55 / 255)
    assert covered == pytest.approx(expected, rel=1e-2)


def test_polygon_outline_band() -> None:
    canvas = Canvas((0.0, 10.0, 0.0, 10.0), 10, supersample=4)
    canvas.polygon(rectangle_vertices(1, 1, 8, 8, 0), WHITE, outline=BLACK, outline_width=1.0)
    img = canvas.image()[..., 0]
    assert np.all(img[1, 1:9] == 0) and np.all(img[2:8, 2:8] == 255)


def test_line_has_its_width() -> None:
    canvas = Canvas((0.0, 10.0, 0.0, 10.0), 100)
    canvas.line((1.0, 5.0), (9.0, 5.0), 1.0, BLACK)
    covered = np.sum(1.0 - canvas.image()[..., 0] / 255.0) / 100
    assert covered == pytest.approx(8.0, rel=1e-3)
    canvas.line((1.0, 1.0), (1.0, 1.0), 1.0, BLACK)  # zero length: nothing drawn
    assert np.sum(1.0 - canvas.image()[..., 0] / 255.0) / 100 == pytest.approx(8.0, rel=1e-3)


def test_shapes_outside_or_across_the_border_are_clipped() -> None:
    canvas = unit_canvas()
    canvas.circle((50.0, 50.0), 1.0, BLACK)
    canvas.polygon(rectangle_vertices(-20, -20, 5, 5, 0.3), BLACK)
    assert np.all(canvas.image() == 255)
    canvas.polygon(rectangle_vertices(-5, -5, 10, 10, 0), BLACK)  # covers the lower-left quarter
    img = canvas.image()[..., 0]
    assert np.all(img[5:, :5] == 0) and np.all(img[:5] == 255) and np.all(img[:, 5:] == 255)


def test_finish_hands_over_the_picture_and_clears() -> None:
    canvas = unit_canvas()
    canvas.circle((5, 5), 3, BLACK)
    expected = canvas.image()
    frame = canvas.finish()
    assert np.array_equal(frame, expected)
    assert np.all(canvas.image() == 255)  # cleared
    canvas.circle((5, 5), 3, BLACK)
    again = canvas.finish()
    assert again is not frame and np.array_equal(again, expected)  # the first frame is untouched
    frame[:] = 7
    assert np.all(canvas.image() == 255)


def test_kept_background_is_restored() -> None:
    canvas = unit_canvas()
    canvas.polygon(rectangle_vertices(0, 0, 10, 5, 0), BLACK)
    canvas.keep_as_background()
    canvas.circle((5, 8), 1, (0, 0, 255))
    canvas.clear()
    img = canvas.image()
    assert np.all(img[5:] == 0) and np.all(img[:5] == 255)
    canvas.circle((5, 8), 1, (0, 0, 255))
    canvas.finish()
    assert np.array_equal(canvas.image(), img)


def test_clear_restores_the_background() -> None:
    canvas = unit_canvas()
    canvas.circle((5, 5), 3, BLACK)
    canvas.clear()
    assert np.all(canvas.image() == 255)


@pytest.mark.parametrize(
    "call",
    [
        lambda c: c.polygon([(0, 0), (1, 1)], BLACK),
        lambda c: c.polygon([(0, 0), (1, np.nan), (1, 0)], BLACK),
        lambda c: c.circle((0, 0), -1.0, BLACK),
        lambda c: c.circle((0, 0), 1.0, (0, 0, 300)),
        lambda c: c.circle((0, 0), 1.0, BLACK, alpha=1.5),
        lambda c: c.line((0, 0), (1, 1), -0.1, BLACK),
    ],
)
def test_bad_input_raises(call: object) -> None:
    with pytest.raises(ValueError):
        call(unit_canvas())  # type: ignore[operator]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"world_bounds": (0, 0, 0, 1), "width_px": 10},
        {"world_bounds": (0, 1, 0, 1), "width_px": 0},
        {"world_bounds": (0, 1, 0, 1), "width_px": 10, "supersample": 0},
    ],
)
def test_bad_canvas_raises(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        Canvas(**kwargs)
