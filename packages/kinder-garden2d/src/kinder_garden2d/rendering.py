"""A small, fast, antialiased 2D rasterizer in pure numpy (no matplotlib).

:class:`Canvas` draws filled polygons, circles and thick lines given in world coordinates (y up)
into an RGB image. Each primitive is drawn only over its bounding box: the signed distance to the
primitive's boundary is computed for every pixel centre there, pixels well inside or outside are
settled by that distance alone, and only the pixels that straddle an edge are supersampled
(``supersample`` × ``supersample`` points each) to get their coverage; the faster ``"analytic"``
mode derives an edge pixel's coverage from the distance itself. Coverage times ``alpha`` is the
blend weight, so edges are antialiased and translucent shapes compose in drawing order. The
canvas keeps 8 bits per channel.

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


def rectangle_vertices(
    x: float, y: float, width: float, height: float, theta: float
) -> NDArray[np.float64]:
    """The 4×2 corners of a rectangle anchored at its bottom-left corner ``(x, y)`` and rotated
    by ``theta`` about that corner (the Kinematic2D convention), counter-clockwise from the
    anchor."""
    c, s = np.cos(theta), np.sin(theta)
    local = np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]])
    rot = np.array([[c, -s], [s, c]])
    out: NDArray[np.float64] = local @ rot.T + np.array([x, y])
    return out


def _check_color(color: Color, what: str) -> tuple[float, float, float]:
    try:
        r, g, b = (float(v) for v in color)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be an (r, g, b) triple in [0, 255], got {color!r}") from None
    if not (0.0 <= r <= 255.0 and 0.0 <= g <= 255.0 and 0.0 <= b <= 255.0):
        raise ValueError(f"{what} must be an (r, g, b) triple in [0, 255], got {color!r}")
    return (r, g, b)


def _check_alpha(alpha: float) -> float:
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha must be in [0, 1], got {alpha!r}")
    return float(alpha)


def _polygon_sdf(vertices: NDArray[np.float64]) -> _SDF:
    """Signed distance to a simple polygon: exact distance to the nearest edge, positive inside
    (even-odd rule, so convex and non-convex simple polygons both work)."""
    edges = []
    for (ax, ay), (bx, by) in zip(vertices, np.roll(vertices, -1, axis=0)):
        dx, dy = float(bx - ax), float(by - ay)
        inv_len2 = 1.0 / max(dx * dx + dy * dy, 1e-300)
        # Horizontal edges never cross a horizontal ray; their slope term is unused.
        slope = dx / dy if dy != 0.0 else 0.0
        edges.append((float(ax), float(ay), float(by), dx, dy, inv_len2, slope))

    def sdf(px: NDArray[np.float64], py: NDArray[np.float64]) -> NDArray[np.float64]:
        shape = np.broadcast_shapes(px.shape, py.shape)
        dist2 = np.full(shape, np.inf)
        inside = np.zeros(shape, dtype=bool)
        for ax, ay, by, dx, dy, inv_len2, slope in edges:
            apx = px - ax
            apy = py - ay
            t = np.clip((apx * dx + apy * dy) * inv_len2, 0.0, 1.0)
            ex = apx - t * dx
            ey = apy - t * dy
            np.minimum(dist2, ex * ex + ey * ey, out=dist2)
            if dy != 0.0:
                crosses = ((ay > py) != (by > py)) & (px < ax + apy * slope)
                np.logical_xor(inside, crosses, out=inside)
        dist = np.sqrt(dist2)
        out: NDArray[np.float64] = np.where(inside, dist, -dist)
        return out

    return sdf


def _convex_sdf(vertices: list[list[float]]) -> _SDF:
    """Signed distance bound for a counter-clockwise convex polygon: the smallest distance to
    the edges' lines.

    Exact inside and on the boundary; outside it never exceeds the true distance, so it
    classifies "wholly outside" pixels conservatively, and its sign is exact.
    """
    edges = []
    n = len(vertices)
    for i in range(n):
        ax, ay = vertices[i]
        bx, by = vertices[(i + 1) % n]
        length = float(np.hypot(bx - ax, by - ay))
        if length == 0.0:
            continue
        nx, ny = -(by - ay) / length, (bx - ax) / length  # inward unit normal
        edges.append((nx, ny, nx * ax + ny * ay))

    def sdf(px: NDArray[np.float64], py: NDArray[np.float64]) -> NDArray[np.float64]:
        # One pass per edge: numpy reduces a short trailing axis slowly.
        nx, ny, o = edges[0]
        out: NDArray[np.float64] = px * nx + py * ny - o
        for nx, ny, o in edges[1:]:
            np.minimum(out, px * nx + py * ny - o, out=out)
        return out

    return sdf


def _orientation(vertices: list[list[float]]) -> tuple[bool, float]:
    """(convex?, signed area) of a polygon; plain Python, as polygons here have few vertices."""
    n = len(vertices)
    area2 = 0.0
    signs = set()
    for i in range(n):
        x0, y0 = vertices[i]
        x1, y1 = vertices[(i + 1) % n]
        x2, y2 = vertices[(i + 2) % n]
        area2 += x0 * y1 - x1 * y0
        cross = (x1 - x0) * (y2 - y1) - (y1 - y0) * (x2 - x1)
        if cross != 0.0:
            signs.add(cross > 0.0)
    return len(signs) <= 1, 0.5 * area2


def _circle_sdf(cx: float, cy: float, radius: float) -> _SDF:
    def sdf(px: NDArray[np.float64], py: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = radius - np.hypot(px - cx, py - cy)
        return out

    return sdf


ANTIALIAS_MODES = ("supersample", "analytic", "none")


class Canvas:
    """An RGB canvas over a world-coordinate box (y up), drawn with antialiased primitives.

    Args:
        world_bounds: ``(xmin, xmax, ymin, ymax)`` of the visible world.
        width_px: The image width in pixels; the height follows from the aspect ratio.
        background: The background colour.
        supersample: Samples per pixel side used for the coverage of edge pixels (1 disables
            antialiasing) in the default ``"supersample"`` mode.
        antialias: ``"supersample"`` (exact coverage of edge pixels from ``supersample²``
            samples each), ``"analytic"`` (coverage from the signed distance at the pixel centre,
            ``clip(d / pixel + ½, 0, 1)``: exact for straight edges along the pixel grid, close
            otherwise, and about twice as fast) or ``"none"``.
    """

    def __init__(
        self,
        world_bounds: tuple[float, float, float, float],
        width_px: int,
        background: tuple[int, int, int] = (255, 255, 255),
        supersample: int = 3,
        antialias: str = "supersample",
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
        if antialias not in ANTIALIAS_MODES:
            raise ValueError(f"antialias must be one of {ANTIALIAS_MODES}, got {antialias!r}")
        self.antialias = antialias
        self.world_bounds = (xmin, xmax, ymin, ymax)
        self.width = int(width_px)
        self.height = max(1, round(self.width * (ymax - ymin) / (xmax - xmin)))
        self.supersample = int(supersample)
        self._px_w = (xmax - xmin) / self.width
        self._px_h = (ymax - ymin) / self.height
        # A pixel whose centre is farther than this from a boundary lies wholly on one side.
        self._half_diag = 0.5 * float(np.hypot(self._px_w, self._px_h))
        self._inv_px = 2.0 / (self._px_w + self._px_h)
        bg = _check_color(background, "background")
        # 8-bit buffer (blending happens in float32 over each primitive's bounding box only), so
        # clearing and reading out a frame are plain byte copies.
        self._buf = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self._buf[:] = np.round(bg).astype(np.uint8)
        self._background = self._buf.copy()
        # World coordinates of the pixel centres along each axis.
        self._xs = np.asarray(xmin + (np.arange(self.width) + 0.5) * self._px_w, np.float64)
        self._ys = np.asarray(ymax - (np.arange(self.height) + 0.5) * self._px_h, np.float64)
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
        outline: a band of ``outline_width`` world units just inside its boundary."""
        v = np.asarray(vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3 or not np.isfinite(v).all():
            raise ValueError(
                f"polygon vertices must be a finite (N, 2) array with N >= 3, got shape {v.shape}"
            )
        vl = v.tolist()
        convex, area = _orientation(vl)
        if area == 0.0:
            return
        sdf = _convex_sdf(vl if area > 0 else vl[::-1]) if convex else _polygon_sdf(v)
        lo, hi = v.min(axis=0), v.max(axis=0)
        self._draw(sdf, lo, hi, fill, alpha, outline, outline_width)

    def circle(
        self,
        center: ArrayLike,
        radius: float,
        fill: tuple[int, int, int],
        alpha: float = 1.0,
        outline: tuple[int, int, int] | None = None,
        outline_width: float = 0.0,
    ) -> None:
        """A filled disc, with an optional outline: a band of ``outline_width`` world units
        just inside its rim."""
        c = np.asarray(center, dtype=np.float64).reshape(-1)
        if c.shape != (2,) or not np.isfinite(c).all():
            raise ValueError(f"circle center must be a finite (x, y), got {center!r}")
        if not (np.isfinite(radius) and radius >= 0):
            raise ValueError(f"circle radius must be finite and >= 0, got {radius!r}")
        sdf = _circle_sdf(float(c[0]), float(c[1]), float(radius))
        lo, hi = c - radius, c + radius
        self._draw(sdf, lo, hi, fill, alpha, outline, outline_width)

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
        """Restore the background (the background colour, or what :meth:`keep_as_background`
        kept). Reuses the buffer, so redrawing frames on one canvas avoids reallocating it."""
        np.copyto(self._buf, self._background)

    def keep_as_background(self) -> None:
        """Make the current picture the background that :meth:`clear` restores (for drawing
        constant scenery once and reusing it every frame)."""
        np.copyto(self._background, self._buf)

    def image(self) -> NDArray[np.uint8]:
        """The current picture as a fresh ``(H, W, 3)`` uint8 array."""
        out: NDArray[np.uint8] = self._buf.copy()
        return out

    # -- internals ------------------------------------------------------------------------------
    def _coverage(
        self,
        sdf: _SDF,
        sd: NDArray[np.float64],
        xs: NDArray[np.float64],
        ys: NDArray[np.float64],
        offset: float,
    ) -> NDArray[np.float32]:
        """Per-pixel coverage of ``{sdf >= offset}`` given ``sd`` at the pixel centres: 0 or 1
        away from the boundary, the supersampled fraction on pixels the boundary crosses."""
        s = sd - offset if offset else sd
        if self.antialias == "analytic":
            # Straight-edge approximation: the fraction of a pixel on the inner side of a line
            # at signed distance s from its centre is about s / pixel + 1/2.
            return np.clip(s * self._inv_px + 0.5, 0.0, 1.0).astype(np.float32)
        if self.antialias == "none":
            return (s >= 0.0).astype(np.float32)
        hd = self._half_diag
        cov = (s >= hd).astype(np.float32)
        edge = np.flatnonzero((s > -hd) & (s < hd))
        if edge.size:
            flat = cov.reshape(-1)
            if self.supersample == 1:
                flat[edge] = s.reshape(-1)[edge] >= 0.0
            else:
                ii, jj = np.divmod(edge, len(xs))
                sx = (xs[jj][:, None] + self._sub_dx).reshape(-1)
                sy = (ys[ii][:, None] + self._sub_dy).reshape(-1)
                inside = (sdf(sx, sy) >= offset).reshape(edge.size, -1)
                flat[edge] = inside.mean(axis=1, dtype=np.float32)
        return cov

    def _draw(
        self,
        sdf: _SDF,
        lo: NDArray[np.float64],
        hi: NDArray[np.float64],
        fill: Color,
        alpha: float,
        outline: Color | None = None,
        outline_width: float = 0.0,
    ) -> None:
        """Blend ``fill`` over the pixels covered by ``{sdf >= 0}`` (within ``[lo, hi]``), with
        ``outline`` over the band ``0 <= sdf < outline_width``."""
        fill_rgb = _check_color(fill, "fill")
        alpha = _check_alpha(alpha)
        has_outline = outline is not None and outline_width > 0.0
        if has_outline and not np.isfinite(outline_width):
            raise ValueError(f"outline_width must be finite, got {outline_width!r}")
        outline_rgb = _check_color(outline, "outline") if outline is not None else fill_rgb
        if alpha <= 0.0:
            return
        xmin, _, _, ymax = self.world_bounds
        j0 = max(int((lo[0] - xmin) / self._px_w) - 1, 0)
        j1 = min(int((hi[0] - xmin) / self._px_w) + 2, self.width)
        i0 = max(int((ymax - hi[1]) / self._px_h) - 1, 0)
        i1 = min(int((ymax - lo[1]) / self._px_h) + 2, self.height)
        if j0 >= j1 or i0 >= i1:
            return
        xs = self._xs[j0:j1]
        ys = self._ys[i0:i1]
        # Pixel centres broadcast as a row of x and a column of y: sd has shape (rows, cols).
        sd = sdf(xs[None, :], ys[:, None])
        region = self._buf[i0:i1, j0:j1]
        f = region.astype(np.float32)
        cov = self._coverage(sdf, sd, xs, ys, 0.0)
        if has_outline:
            inner = self._coverage(sdf, sd, xs, ys, float(outline_width))
            if alpha != 1.0:
                cov *= np.float32(alpha)
                inner *= np.float32(alpha)
            f += (np.asarray(outline_rgb, np.float32) - f) * cov[:, :, None]
            f += (np.asarray(fill_rgb, np.float32) - f) * inner[:, :, None]
        else:
            if alpha != 1.0:
                cov *= np.float32(alpha)
            f += (np.asarray(fill_rgb, np.float32) - f) * cov[:, :, None]
        f += 0.5
        region[...] = f
