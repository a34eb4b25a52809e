"""A small, fast, antialiased 2D rasterizer in pure numpy (no matplotlib).

:class:`Canvas` draws filled polygons, circles and thick lines given in world coordinates (y up)
into an RGB image. Each primitive is drawn only over its bounding box: the signed distance to the
primitive's boundary is computed for every pixel centre there, pixels well inside or outside are
settled by that distance alone, and only the pixels that straddle an edge are supersampled
(``supersample`` × ``supersample`` points each) to get their coverage. Coverage times ``alpha`` is
the blend weight, so edges are antialiased and translucent shapes compose in drawing order.

Example::

    canvas = Canvas((0.0, 2.0, 0.0, 1.0), width_px=400)
    canvas.polygon(rectangle_vertices(0.2, 0.1, 0.5, 0.3, 0.3), fill=(200, 0, 0))
    canvas.circle((1.5, 0.5), 0.2, fill=(0, 0, 200), alpha=0.5, outline=(0, 0, 0),
                  outline_width=0.01)
    frame = canvas.image()  # (200, 400, 3) uint8
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

Color = tuple[int, int, int]
# A signed distance function: (x, y) flat arrays → distance to the boundary, positive inside.
_SDF = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]


def rectangle_vertices(x: float, y: float, width: float, height: float, theta: float) -> NDArray:
    """The 4×2 corners of a rectangle anchored at its bottom-left corner ``(x, y)`` and rotated
    by ``theta`` about that corner (the Kinematic2D convention), counter-clockwise from the
    anchor."""
    c, s = np.cos(theta), np.sin(theta)
    local = np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]])
    rot = np.array([[c, -s], [s, c]])
    out: NDArray = local @ rot.T + np.array([x, y])
    return out


def _check_color(color: Color, what: str) -> NDArray[np.float32]:
    arr = np.asarray(color, dtype=np.float32).reshape(-1)
    if arr.shape != (3,) or not np.all((arr >= 0) & (arr <= 255)):
        raise ValueError(f"{what} must be an (r, g, b) triple of ints in [0, 255], got {color!r}")
    return arr


def _check_alpha(alpha: float) -> float:
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha must be in [0, 1], got {alpha!r}")
    return float(alpha)


def _polygon_sdf(vertices: NDArray[np.float64]) -> _SDF:
    """Signed distance to a simple polygon: exact distance to the nearest edge, positive inside
    (even-odd rule, so convex and non-convex simple polygons both work)."""
    a = vertices
    b = np.roll(vertices, -1, axis=0)
    ab = b - a
    len2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    ay, by = a[:, 1], b[:, 1]
    dy = by - ay
    # Edges with dy == 0 never cross a horizontal ray; avoid dividing by zero for them.
    inv_dy = np.where(dy != 0.0, 1.0 / np.where(dy != 0.0, dy, 1.0), 0.0)

    def sdf(px: NDArray[np.float64], py: NDArray[np.float64]) -> NDArray[np.float64]:
        apx = px[:, None] - a[None, :, 0]
        apy = py[:, None] - a[None, :, 1]
        t = np.clip((apx * ab[:, 0] + apy * ab[:, 1]) / len2, 0.0, 1.0)
        ex = apx - t * ab[:, 0]
        ey = apy - t * ab[:, 1]
        dist = np.sqrt(np.min(ex * ex + ey * ey, axis=1))
        straddles = (ay[None, :] > py[:, None]) != (by[None, :] > py[:, None])
        x_cross = a[None, :, 0] + apy * (ab[:, 0] * inv_dy)[None, :]
        inside = (np.count_nonzero(straddles & (px[:, None] < x_cross), axis=1) & 1).astype(bool)
        out: NDArray[np.float64] = np.where(inside, dist, -dist)
        return out

    return sdf


def _convex_sdf(vertices: NDArray[np.float64]) -> _SDF:
    """Signed distance bound for a convex polygon: the smallest distance to the edges' lines.

    Exact inside and on the boundary; outside it never exceeds the true distance, so it
    classifies "wholly outside" pixels conservatively, and its sign is exact.
    """
    a = vertices
    ab = np.roll(vertices, -1, axis=0) - a
    # Inward unit normals (the vertices are counter-clockwise).
    n = np.stack([-ab[:, 1], ab[:, 0]], axis=1)
    n /= np.maximum(np.hypot(n[:, 0], n[:, 1]), 1e-300)[:, None]
    offset = np.einsum("ij,ij->i", n, a)

    def sdf(px: NDArray[np.float64], py: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = np.min(
            px[:, None] * n[:, 0] + py[:, None] * n[:, 1] - offset, axis=1
        )
        return out

    return sdf


def _orientation(vertices: NDArray[np.float64]) -> tuple[bool, float]:
    """(convex?, signed area) of a polygon."""
    d = np.roll(vertices, -1, axis=0) - vertices
    cross = d[:, 0] * np.roll(d[:, 1], -1) - d[:, 1] * np.roll(d[:, 0], -1)
    area = 0.5 * float(
        np.sum(
            vertices[:, 0] * np.roll(vertices[:, 1], -1)
            - np.roll(vertices[:, 0], -1) * vertices[:, 1]
        )
    )
    nz = cross[np.abs(cross) > 1e-15 * max(1.0, float(np.abs(cross).max(initial=0.0)))]
    convex = bool(nz.size == 0 or np.all(nz > 0) or np.all(nz < 0))
    return convex, area


def _circle_sdf(cx: float, cy: float, radius: float) -> _SDF:
    def sdf(px: NDArray[np.float64], py: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = radius - np.hypot(px - cx, py - cy)
        return out

    return sdf


def _stroke_sdf(inner: _SDF, half_width: float) -> _SDF:
    """The band of half-width ``half_width`` centred on ``inner``'s boundary."""

    def sdf(px: NDArray[np.float64], py: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = half_width - np.abs(inner(px, py))
        return out

    return sdf


class Canvas:
    """An RGB canvas over a world-coordinate box (y up), drawn with antialiased primitives.

    Args:
        world_bounds: ``(xmin, xmax, ymin, ymax)`` of the visible world.
        width_px: The image width in pixels; the height follows from the aspect ratio.
        background: The background colour.
        supersample: Samples per pixel side used for the coverage of edge pixels (1 disables
            antialiasing).
    """

    def __init__(
        self,
        world_bounds: tuple[float, float, float, float],
        width_px: int,
        background: tuple[int, int, int] = (255, 255, 255),
        supersample: int = 3,
    ) -> None:
        xmin, xmax, ymin, ymax = (float(v) for v in world_bounds)
        if not (np.isfinite([xmin, xmax, ymin, ymax]).all() and xmax > xmin and ymax > ymin):
            raise ValueError(
                f"world_bounds must be finite (xmin, xmax, ymin, ymax) with xmin < xmax and "
                f"ymin < ymax, got {world_bounds!r}"
            )
        if int(width_px) != width_px or width_px < 1:
            raise ValueError(f"width_px must be a positive int, got {width_px!r}")
        if int(supersample) != supersample or supersample < 1:
            raise ValueError(f"supersample must be a positive int, got {supersample!r}")
        self.world_bounds = (xmin, xmax, ymin, ymax)
        self.width = int(width_px)
        self.height = max(1, round(self.width * (ymax - ymin) / (xmax - xmin)))
        self.supersample = int(supersample)
        self._px_w = (xmax - xmin) / self.width
        self._px_h = (ymax - ymin) / self.height
        # A pixel whose centre is farther than this from a boundary lies wholly on one side.
        self._half_diag = 0.5 * float(np.hypot(self._px_w, self._px_h))
        bg = _check_color(background, "background")
        self._background = bg
        self._buf = np.empty((self.height, self.width, 3), dtype=np.float32)
        self._buf[:] = bg
        k = (np.arange(self.supersample) + 0.5) / self.supersample - 0.5
        ox, oy = np.meshgrid(k * self._px_w, k * self._px_h)
        self._sub_dx = ox.reshape(-1)
        self._sub_dy = oy.reshape(-1)

    # -- primitives -----------------------------------------------------------------------------
    def polygon(
        self,
        vertices: ArrayLike,
        fill: tuple[int, int, int],
        alpha: float = 1.0,
        outline: tuple[int, int, int] | None = None,
        outline_width: float = 0.0,
    ) -> None:
        """A filled polygon (``(N, 2)`` world coordinates, convex or simple), with an optional
        outline of ``outline_width`` world units centred on its boundary."""
        v = np.asarray(vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3 or not np.isfinite(v).all():
            raise ValueError(
                f"polygon vertices must be a finite (N, 2) array with N >= 3, got shape {v.shape}"
            )
        convex, area = _orientation(v)
        if area == 0.0:
            return
        sdf = _convex_sdf(v if area > 0 else v[::-1]) if convex else _polygon_sdf(v)
        lo, hi = v.min(axis=0), v.max(axis=0)
        self._draw(sdf, lo, hi, _check_color(fill, "fill"), _check_alpha(alpha))
        self._outline(sdf, lo, hi, outline, outline_width, alpha)

    def circle(
        self,
        center: ArrayLike,
        radius: float,
        fill: tuple[int, int, int],
        alpha: float = 1.0,
        outline: tuple[int, int, int] | None = None,
        outline_width: float = 0.0,
    ) -> None:
        """A filled disc, with an optional outline centred on its rim."""
        c = np.asarray(center, dtype=np.float64).reshape(-1)
        if c.shape != (2,) or not np.isfinite(c).all():
            raise ValueError(f"circle center must be a finite (x, y), got {center!r}")
        if not (np.isfinite(radius) and radius >= 0):
            raise ValueError(f"circle radius must be finite and >= 0, got {radius!r}")
        sdf = _circle_sdf(float(c[0]), float(c[1]), float(radius))
        lo, hi = c - radius, c + radius
        self._draw(sdf, lo, hi, _check_color(fill, "fill"), _check_alpha(alpha))
        self._outline(sdf, lo, hi, outline, outline_width, alpha)

    def line(
        self,
        p0: ArrayLike,
        p1: ArrayLike,
        width: float,
        color: tuple[int, int, int],
        alpha: float = 1.0,
    ) -> None:
        """A straight segment of ``width`` world units with square (butt) ends."""
        a = np.asarray(p0, dtype=np.float64).reshape(-1)
        b = np.asarray(p1, dtype=np.float64).reshape(-1)
        if a.shape != (2,) or b.shape != (2,) or not np.isfinite([*a, *b]).all():
            raise ValueError(f"line endpoints must be finite (x, y) pairs, got {p0!r}, {p1!r}")
        if not (np.isfinite(width) and width >= 0):
            raise ValueError(f"line width must be finite and >= 0, got {width!r}")
        d = b - a
        length = float(np.hypot(d[0], d[1]))
        if length == 0.0 or width == 0.0:
            return
        n = np.array([-d[1], d[0]]) / length * (0.5 * width)
        self.polygon(np.array([a - n, b - n, b + n, a + n]), color, alpha)

    def clear(self) -> None:
        """Paint the whole canvas with the background again (reuses the buffer, so redrawing
        frames on one canvas avoids reallocating it)."""
        self._buf[:] = self._background

    def image(self) -> NDArray[np.uint8]:
        """The current picture as a fresh ``(H, W, 3)`` uint8 array."""
        out: NDArray[np.uint8] = (self._buf + 0.5).astype(np.uint8)
        return out

    # -- internals ------------------------------------------------------------------------------
    def _outline(
        self,
        sdf: _SDF,
        lo: NDArray[np.float64],
        hi: NDArray[np.float64],
        outline: Color | None,
        outline_width: float,
        alpha: float,
    ) -> None:
        if outline is None or outline_width <= 0.0:
            return
        if not np.isfinite(outline_width):
            raise ValueError(f"outline_width must be finite, got {outline_width!r}")
        half = 0.5 * float(outline_width)
        color = _check_color(outline, "outline")
        self._draw(_stroke_sdf(sdf, half), lo - half, hi + half, color, alpha)

    def _draw(
        self,
        sdf: _SDF,
        lo: NDArray[np.float64],
        hi: NDArray[np.float64],
        color: NDArray[np.float32],
        alpha: float,
    ) -> None:
        """Blend ``color`` over the pixels covered by ``{sdf >= 0}`` (within ``[lo, hi]``)."""
        if alpha <= 0.0:
            return
        xmin, _, _, ymax = self.world_bounds
        j0 = max(int(np.floor((lo[0] - xmin) / self._px_w)) - 1, 0)
        j1 = min(int(np.ceil((hi[0] - xmin) / self._px_w)) + 1, self.width)
        i0 = max(int(np.floor((ymax - hi[1]) / self._px_h)) - 1, 0)
        i1 = min(int(np.ceil((ymax - lo[1]) / self._px_h)) + 1, self.height)
        if j0 >= j1 or i0 >= i1:
            return
        xs = xmin + (np.arange(j0, j1) + 0.5) * self._px_w
        ys = ymax - (np.arange(i0, i1) + 0.5) * self._px_h
        nj = j1 - j0
        px = np.tile(xs, i1 - i0)
        py = np.repeat(ys, nj)
        sd = sdf(px, py)
        cov = (sd >= self._half_diag).astype(np.float32)
        edge = np.flatnonzero(np.abs(sd) < self._half_diag)
        if edge.size:
            if self.supersample == 1:
                cov[edge] = sd[edge] >= 0.0
            else:
                sx = (px[edge, None] + self._sub_dx[None, :]).reshape(-1)
                sy = (py[edge, None] + self._sub_dy[None, :]).reshape(-1)
                inside = sdf(sx, sy).reshape(edge.size, -1) >= 0.0
                cov[edge] = inside.mean(axis=1)
        weight = cov.reshape(i1 - i0, nj, 1) * np.float32(alpha)
        region = self._buf[i0:i1, j0:j1]
        region += (color - region) * weight
