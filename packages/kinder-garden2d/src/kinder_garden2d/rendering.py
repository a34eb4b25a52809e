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

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

Color = tuple[int, int, int]
F32 = NDArray[np.float32]
# A signed distance function: (x, y) flat arrays → distance to the boundary, positive inside.
_SDF = Callable[[F32, F32], F32]


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

    def sdf(px: F32, py: F32) -> F32:
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
        out: F32 = np.where(inside, dist, -dist).astype(np.float32)
        return out

    return sdf


def _convex_sdf(vertices: list[list[float]]) -> _SDF:
    """Signed distance bound for a counter-clockwise convex polygon: the smallest distance to
    the edges' lines.

    Exact inside and on the boundary; outside it never exceeds the true distance, so it
    classifies "wholly outside" pixels conservatively, and its sign is exact.
    """
    normals = []
    n = len(vertices)
    for i in range(n):
        ax, ay = vertices[i]
        bx, by = vertices[(i + 1) % n]
        length = math.hypot(bx - ax, by - ay)
        if length > 0.0:
            nx, ny = -(by - ay) / length, (bx - ax) / length  # inward unit normal
            normals.append((nx, ny, nx * ax + ny * ay))
    e = np.array(normals, dtype=np.float32)
    enx, eny, off = e[:, 0:1], e[:, 1:2], e[:, 2:3]

    def sdf(px: F32, py: F32) -> F32:
        if px.ndim == 2 and px.shape[0] == 1 and py.shape[1] == 1:
            # Pixel grid (a row of x, a column of y): per-edge rows and columns, one full-size
            # sum, and a minimum over the leading (edge) axis.
            rows = enx * px - off  # (edges, w)
            cols = eny * py.reshape(1, -1)  # (edges, h)
            out: F32 = np.min(rows[:, None, :] + cols[:, :, None], axis=0)
            return out
        flat = enx * px.reshape(1, -1) + eny * py.reshape(1, -1) - off
        res: F32 = np.min(flat, axis=0).reshape(np.broadcast_shapes(px.shape, py.shape))
        return res

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
    def sdf(px: F32, py: F32) -> F32:
        dx = px - np.float32(cx)
        dy = py - np.float32(cy)
        out: F32 = np.float32(radius) - np.sqrt(dx * dx + dy * dy)
        return out

    return sdf


ANTIALIAS_MODES = ("supersample", "analytic", "none")


def _blend(f: F32, color: tuple[float, float, float], weight: F32) -> F32:
    """``f + (color − f)·weight`` in place, for ``f`` of shape (h, 3w) (interleaved RGB rows)
    and ``weight`` of shape (h, w).

    Rows stay long and contiguous: broadcasting over a trailing axis of length 3 would make
    numpy loop in steps of three.
    """
    row = np.tile(np.asarray(color, dtype=np.float32), weight.shape[1])
    keep = np.repeat(np.float32(1.0) - weight, 3, axis=1)
    f -= row
    f *= keep
    f += row
    return f


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
        self._xs = np.asarray(xmin + (np.arange(self.width) + 0.5) * self._px_w, np.float32)
        self._ys = np.asarray(ymax - (np.arange(self.height) + 0.5) * self._px_h, np.float32)
        k = (np.arange(self.supersample) + 0.5) / self.supersample - 0.5
        ox, oy = np.meshgrid(k * self._px_w, k * self._px_h)
        self._sub_dx = ox.reshape(-1).astype(np.float32)
        self._sub_dy = oy.reshape(-1).astype(np.float32)
        # True once finish() handed the buffer itself to the caller: the canvas then starts over
        # from a copy of the background.
        self._handed_out = False

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
        if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3:
            raise ValueError(f"polygon vertices must be an (N, 2) array with N >= 3, got {v.shape}")
        vl = v.tolist()
        xs, ys = [p[0] for p in vl], [p[1] for p in vl]
        lo, hi = (min(xs), min(ys)), (max(xs), max(ys))
        if not math.isfinite(sum(xs) + sum(ys)):
            raise ValueError(f"polygon vertices must be finite, got {vl}")
        convex, area = _orientation(vl)
        if area == 0.0:
            return
        sdf = _convex_sdf(vl if area > 0 else vl[::-1]) if convex else _polygon_sdf(v)
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
        x, y, r = float(c[0]), float(c[1]), float(radius)
        self._draw(sdf, (x - r, y - r), (x + r, y + r), fill, alpha, outline, outline_width)

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
        if self._handed_out:
            self._buf = self._background.copy()
            self._handed_out = False
        else:
            np.copyto(self._buf, self._background)

    def keep_as_background(self) -> None:
        """Make the current picture the background that :meth:`clear` restores (for drawing
        constant scenery once and reusing it every frame)."""
        np.copyto(self._background, self._own_buffer())

    def image(self) -> NDArray[np.uint8]:
        """The current picture as a fresh ``(H, W, 3)`` uint8 array."""
        out: NDArray[np.uint8] = self._own_buffer().copy()
        return out

    def finish(self) -> NDArray[np.uint8]:
        """The current picture as a fresh ``(H, W, 3)`` uint8 array, handing over the canvas's
        own buffer instead of copying it; the canvas is left cleared. (``image()`` then
        ``clear()`` in one step, for drawing frame after frame.)"""
        out = self._own_buffer()
        self._handed_out = True
        return out

    def _own_buffer(self) -> NDArray[np.uint8]:
        if self._handed_out:
            self._buf = self._background.copy()
            self._handed_out = False
        return self._buf

    # -- internals ------------------------------------------------------------------------------
    def _coverage(
        self,
        sdf: _SDF,
        sd: F32,
        xs: F32,
        ys: F32,
        offset: float,
    ) -> NDArray[np.float32]:
        """Per-pixel coverage of ``{sdf >= offset}`` given ``sd`` at the pixel centres: 0 or 1
        away from the boundary, the supersampled fraction on pixels the boundary crosses."""
        s = sd - offset if offset else sd
        if self.antialias == "analytic":
            # Straight-edge approximation: the fraction of a pixel on the inner side of a line
            # at signed distance s from its centre is about s / pixel + 1/2.
            cov: F32 = s * np.float32(self._inv_px)
            cov += np.float32(0.5)
            np.maximum(cov, np.float32(0.0), out=cov)
            np.minimum(cov, np.float32(1.0), out=cov)
            return cov
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
        lo: tuple[float, float],
        hi: tuple[float, float],
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
        # The region as (rows, 3·cols): a view, since each row's pixels are contiguous.
        rows = self._own_buffer()[i0:i1, j0:j1].reshape(i1 - i0, 3 * (j1 - j0))
        cov = self._coverage(sdf, sd, xs, ys, 0.0)
        if alpha != 1.0:
            cov *= np.float32(alpha)
        if has_outline:
            inner = self._coverage(sdf, sd, xs, ys, float(outline_width))
            if alpha != 1.0:
                inner *= np.float32(alpha)
            # Outline over the whole shape, then the fill over its inner part.
            f = _blend(rows.astype(np.float32), outline_rgb, cov)
            f = _blend(f, fill_rgb, inner)
        else:
            f = _blend(rows.astype(np.float32), fill_rgb, cov)
        f += np.float32(0.5)
        rows[...] = f
