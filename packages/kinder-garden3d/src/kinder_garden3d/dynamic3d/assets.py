"""Fixtures and objects of the Dynamic3D tasks, generated as MJCF from primitive shapes.

Nothing is downloaded: every asset is built here from boxes, cylinders and capsules. Each asset
type declares its parameters (name → default) in :data:`OBJECT_PARAMS` / :data:`FIXTURE_PARAMS`;
task files may override any of them and nothing else (checked on load).

Conventions (all lengths in metres, masses in kg, sizes are *full* extents):

* A movable object's body frame is the centre of its axis-aligned bounding box in its resting
  orientation, so the features ``x, y, z`` are the box centre and ``bb_x, bb_y, bb_z`` its size.
  (The seesaw is the exception: its frame is the pivot block's centre.)
* A fixture's frame is the centre of its footprint on the floor (z = 0 at its bottom). Fixtures
  are MuJoCo *mocap* bodies, so their pose is part of the simulator state and can be sampled.
* Region frames of a fixture are named: ``top`` (the top surface), ``shelf:K`` (the top surface
  of board K of a cupboard, 0 = bottom board) and ``shelf:K/partition:P`` (the floor of cell P of
  level K; inside the drawer when that cell has one, so the frame moves with the drawer).
  A seesaw has the frame ``beam`` (the beam's centre, tilting with the hinge).

Collision filtering uses bitmasks: fixtures and the floor never collide with each other
(contype 2, conaffinity 1); objects, drawers and the robot collide with everything, except a
drawer with its own fixture (the scene excludes that pair; the drawer's slide joint and its
limits hold it).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from kinder_garden3d.dynamic3d.geometry import Array, pose_matrix

Params = dict[str, Any]

FIXTURE_CLASS = "d3_fixture"
OBJECT_CLASS = "d3_object"
VISUAL_CLASS = "d3_visual"

#: MJCF <default> classes used by every asset.
DEFAULT_CLASSES = f"""    <default class="{FIXTURE_CLASS}">
      <geom contype="2" conaffinity="1" group="0" condim="3"/>
    </default>
    <default class="{OBJECT_CLASS}">
      <geom contype="1" conaffinity="3" group="0" condim="4"/>
    </default>
    <default class="{VISUAL_CLASS}">
      <geom contype="0" conaffinity="0" group="0" density="0"/>
    </default>"""

WOOD = (0.714, 0.690, 0.624, 1.0)
WOOD_LIGHT = (0.949, 0.949, 0.949, 1.0)
DRAWER_FACE = (0.918, 0.894, 0.835, 1.0)
BLACK = (0.05, 0.05, 0.05, 1.0)


def _f(values: Sequence[float] | Array) -> str:
    return " ".join(f"{float(v):.6g}" for v in values)


def _geom(
    kind: str,
    size: Sequence[float],
    pos: Sequence[float],
    rgba: Sequence[float],
    cls: str,
    *,
    euler: Sequence[float] | None = None,
    density: float | None = None,
    friction: Sequence[float] | None = None,
    name: str | None = None,
) -> str:
    attrs = [f'type="{kind}"', f'size="{_f(size)}"', f'pos="{_f(pos)}"', f'rgba="{_f(rgba)}"']
    attrs.append(f'class="{cls}"')
    if name is not None:
        attrs.insert(0, f'name="{name}"')
    if euler is not None:
        attrs.append(f'euler="{_f(euler)}"')
    if density is not None:
        attrs.append(f'density="{density:.6g}"')
    if friction is not None:
        attrs.append(f'friction="{_f(friction)}"')
    return f"<geom {' '.join(attrs)}/>"


@dataclass
class _Box:
    """An axis-aligned box (centre, full size) or a cylinder/capsule (``kind``) in a body."""

    centre: tuple[float, float, float]
    size: tuple[float, float, float]
    rgba: Sequence[float]
    kind: str = "box"
    euler: tuple[float, float, float] | None = None
    collide: bool = True

    def volume(self) -> float:
        if self.kind == "box":
            return self.size[0] * self.size[1] * self.size[2]
        # cylinder: size = (diameter, diameter, length) in its own frame
        return math.pi * (self.size[0] / 2.0) ** 2 * self.size[2]

    def xml(self, density: float, friction: Sequence[float] | None, name: str | None) -> str:
        cls = OBJECT_CLASS if self.collide else VISUAL_CLASS
        if self.kind == "box":
            size: tuple[float, ...] = tuple(s / 2.0 for s in self.size)
        else:
            size = (self.size[0] / 2.0, self.size[2] / 2.0)
        return _geom(
            self.kind,
            size,
            self.centre,
            self.rgba,
            cls,
            euler=self.euler,
            density=density if self.collide else None,
            friction=friction if self.collide else None,
            name=name,
        )


def _parts_xml(name: str, parts: list[_Box], mass: float, friction: Sequence[float] | None) -> str:
    """Geoms of ``parts`` whose density makes the collision parts weigh ``mass`` in total."""
    volume = sum(p.volume() for p in parts if p.collide)
    density = mass / volume
    return "\n".join(p.xml(density, friction, f"{name}_g{i}") for i, p in enumerate(parts))


def _bbox(parts: list[_Box]) -> tuple[Array, Array]:
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for p in parts:
        if not p.collide:
            continue
        if p.kind == "box":
            half = np.array(p.size) / 2.0
        else:  # cylinders here are only ever axis-aligned along x, y or z
            r, length = p.size[0] / 2.0, p.size[2] / 2.0
            if p.kind == "capsule":
                length += r
            half = np.array([r, r, length])
            if p.euler is not None and abs(p.euler[1]) > 1e-9:  # axis along x
                half = np.array([length, r, r])
            elif p.euler is not None and abs(p.euler[0]) > 1e-9:  # axis along y
                half = np.array([r, length, r])
        c = np.array(p.centre)
        lo = np.minimum(lo, c - half)
        hi = np.maximum(hi, c + half)
    return lo, hi


def _vec3(v: Array) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _centred(parts: list[_Box]) -> tuple[list[_Box], Array]:
    """Shift parts so the bounding-box centre is the origin; return them and the bbox size."""
    lo, hi = _bbox(parts)
    mid = (lo + hi) / 2.0
    out = [
        _Box(_vec3(np.array(p.centre) - mid), p.size, p.rgba, p.kind, p.euler, p.collide)
        for p in parts
    ]
    return out, hi - lo


# ---------------------------------------------------------------------------------------------
# Movable objects


@dataclass
class ObjectAsset:
    """A generated movable object.

    ``body(name, pos, quat)`` returns the MJCF body (with a free joint ``<name>_joint``);
    ``bbox`` is the full bounding-box size; ``bottom`` the height of the body origin above the
    object's lowest point when resting; ``hinge`` names an internal hinge joint (seesaw);
    ``frames`` maps extra region-frame names to :class:`HingeFrame`.
    """

    geoms: str
    bbox: Array
    bottom: float
    children: str = ""
    hinge: str | None = None
    frames: dict[str, HingeFrame] = field(default_factory=dict)

    def body(self, name: str, pos: Sequence[float], quat: Sequence[float] | Array) -> str:
        return (
            f'<body name="{name}" pos="{_f(pos)}" quat="{_f(quat)}">\n'
            f'<freejoint name="{name}_joint"/>\n{self.geoms}\n{self.children}\n</body>'
        )


@dataclass(frozen=True)
class HingeFrame:
    """A frame on a hinged child: T(pivot) · R(axis, angle) · T(offset), in the object frame."""

    pivot: tuple[float, float, float]
    axis: tuple[float, float, float]
    offset: tuple[float, float, float]


def _simple(name: str, parts: list[_Box], mass: float, friction: Sequence[float]) -> ObjectAsset:
    parts, size = _centred(parts)
    return ObjectAsset(_parts_xml(name, parts, mass, friction), size, float(size[2] / 2.0))


def _cube(name: str, p: Params) -> ObjectAsset:
    s = float(p["size"])
    mass = p["mass"] if p["mass"] is not None else 600.0 * s**3
    return _simple(name, [_Box((0, 0, 0), (s, s, s), p["rgba"])], mass, p["friction"])


def _cuboid(name: str, p: Params) -> ObjectAsset:
    sx, sy, sz = (float(v) for v in p["size"])
    mass = p["mass"] if p["mass"] is not None else 600.0 * sx * sy * sz
    return _simple(name, [_Box((0, 0, 0), (sx, sy, sz), p["rgba"])], mass, p["friction"])


def _open_box(size: Sequence[float], wall: float, rgba: Sequence[float]) -> list[_Box]:
    """A box open at the top: a floor and four walls, bottom at z = 0.

    The walls stand on the floor plate (not beside it down to z = 0), so only the plate touches
    the support: 4 contacts instead of 20 (a large share of the simulation cost)."""
    sx, sy, sz = (float(v) for v in size)
    hw = sz - wall  # wall height above the plate
    zc = wall + hw / 2
    return [
        _Box((0, 0, wall / 2), (sx, sy, wall), rgba),
        _Box(((sx - wall) / 2, 0, zc), (wall, sy, hw), rgba),
        _Box((-(sx - wall) / 2, 0, zc), (wall, sy, hw), rgba),
        _Box((0, (sy - wall) / 2, zc), (sx - 2 * wall, wall, hw), rgba),
        _Box((0, -(sy - wall) / 2, zc), (sx - 2 * wall, wall, hw), rgba),
    ]


def _bin(name: str, p: Params) -> ObjectAsset:
    """An open bin. ``origin`` is its body frame: ``"centre"`` (the bounding-box centre) or
    ``"bottom"`` (the centre of its bottom face, upstream kindergarden 0.2.5's bin frame, so the
    observed ``z`` is the height of the surface it stands on)."""
    parts = _open_box(p["size"], p["wall"], p["rgba"])
    if p["origin"] == "centre":
        return _simple(name, parts, p["mass"], p["friction"])
    if p["origin"] != "bottom":
        raise ValueError(f"bin {name!r}: origin must be 'centre' or 'bottom', got {p['origin']!r}")
    lo, hi = _bbox(parts)
    return ObjectAsset(_parts_xml(name, parts, p["mass"], p["friction"]), hi - lo, 0.0)


def _bowl(name: str, p: Params) -> ObjectAsset:
    """A bowl: a disc and a ring of ``segments`` flared wall slats (a primitive stand-in for the
    RoboCasa mesh). ``origin`` is its body frame: ``"centre"`` (the bounding-box centre) or
    ``"rim"`` (the centre of its rim's plane, upstream kindergarden 0.2.5's generated bowl
    frame, so the observed ``z`` is the rim's height)."""
    d, h, wall, n = float(p["diameter"]), float(p["height"]), float(p["wall"]), int(p["segments"])
    if p["origin"] not in ("centre", "rim"):
        raise ValueError(f"bowl {name!r}: origin must be 'centre' or 'rim', got {p['origin']!r}")
    dz = -h / 2 if p["origin"] == "rim" else 0.0  # the bounding-box centre in the body frame
    base_r = d * 0.3
    rim_r = d / 2 - wall / 2
    flare = math.atan2(rim_r - base_r, h)  # tilt of the slats away from the axis
    # Length such that a tilted slat (thickness included) spans exactly the bowl's height.
    slat_len = (h - wall * math.sin(flare)) / math.cos(flare)
    slat_w = 2 * math.pi * rim_r / n * 1.1
    volume = math.pi * base_r**2 * wall + n * slat_w * wall * slat_len
    density = float(p["mass"]) / volume
    common = f'rgba="{_f(p["rgba"])}" class="{OBJECT_CLASS}" density="{density:.6g}" ' + (
        f'friction="{_f(p["friction"])}"'
    )
    lines = [
        f'<geom name="{name}_g0" type="cylinder" size="{base_r:.6g} {wall / 2:.6g}" '
        f'pos="0 0 {dz - h / 2 + wall / 2:.6g}" {common}/>'
    ]
    r_mid = (base_r + rim_r) / 2
    for k in range(n):
        a = 2 * math.pi * k / n
        lines.append(
            f'<geom name="{name}_s{k}" type="box" '
            f'size="{_f((wall / 2, slat_w / 2, slat_len / 2))}" '
            f'pos="{_f((r_mid * math.cos(a), r_mid * math.sin(a), dz))}" '
            f'quat="{_f(_quat_zy(a, flare))}" {common}/>'
        )
    return ObjectAsset("\n".join(lines), np.array([d, d, h]), h / 2 - dz)


def _quat_zy(yaw: float, pitch: float) -> tuple[float, float, float, float]:
    """The (w, x, y, z) quaternion of Rz(yaw) · Ry(pitch)."""
    cz, sz, cy, sy = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(pitch / 2), math.sin(pitch / 2)
    return (cz * cy, -sz * sy, cz * sy, sz * cy)


def _drink_box(name: str, p: Params) -> ObjectAsset:
    """A boxed drink: a box with a label band and a straw (stand-in for the RoboCasa mesh)."""
    sx, sy, sz = (float(v) for v in p["size"])
    white = (0.9, 0.9, 0.9, 1.0)
    parts = [
        _Box((0, 0, sz / 2), (sx, sy, sz), p["rgba"]),
        _Box((0, 0, sz * 0.6), (sx * 1.01, sy * 1.01, sz * 0.3), p["label_rgba"], collide=False),
        _Box((sx * 0.25, 0, sz + 0.01), (0.006, 0.006, 0.02), white, "cylinder", collide=False),
    ]
    return _simple(name, parts, p["mass"], p["friction"])


def _can(name: str, p: Params) -> ObjectAsset:
    d, h = float(p["diameter"]), float(p["height"])
    parts = [
        _Box((0, 0, h / 2), (d, d, h), p["rgba"], "cylinder"),
        _Box(
            (0, 0, h * 0.5), (d * 1.01, d * 1.01, h * 0.4), p["label_rgba"], "cylinder", None, False
        ),
    ]
    return _simple(name, parts, p["mass"], p["friction"])


def _screw(name: str, p: Params) -> ObjectAsset:
    """A screw lying along x: a short fat head and a thinner shaft, both capsules (a stand-in for
    the scaled fastener meshes; capsules collide much faster than cylinders).

    Its contacts are stiffer than MuJoCo's default (``solref`` time constant 4 ms instead of
    20 ms): a 20 g screw swept off a counter falls 0.26 m, and with the default soft contact it
    sank through the 1 cm floor of a drawer in most tumbling drops."""
    length, head_d, head_l, shaft_d = (
        float(p["length"]), float(p["head_diameter"]), float(p["head_length"]),
        float(p["shaft_diameter"]),
    )  # fmt: skip
    along_x = (0.0, math.pi / 2, 0.0)
    head_r, shaft_r = head_d / 2, shaft_d / 2
    shaft_len = length - head_l
    parts = [
        # capsule sizes: (diameter, diameter, straight length); the caps add a radius each end
        _Box((head_l / 2, 0, 0), (head_d, head_d, max(head_l - head_d, 1e-4)), p["rgba"],
             "capsule", along_x),
        _Box((head_l + shaft_len / 2, 0, 0), (shaft_d, shaft_d, max(shaft_len - shaft_d, 1e-4)),
             p["rgba"], "capsule", along_x),
    ]  # fmt: skip
    del head_r, shaft_r
    asset = _simple(name, parts, p["mass"], p["friction"])
    solref = f'<geom solref="{_f(p["solref"])}" '
    return replace(asset, geoms=asset.geoms.replace("<geom ", solref))


def _wiper(name: str, p: Params) -> ObjectAsset:
    """A wiper / broom: with ``upright`` false (the default), lying flat: a handle along x and a
    head across it; with ``upright`` true, standing on its head: a head of ``head_length`` along
    x, ``head_width`` along y and ``head_height`` tall, and the handle (``handle_length`` tall)
    rising from its middle (upstream kindergarden 0.2.5's default wiper).

    ``head_side`` puts a flat wiper's head at the handle's ``"+x"`` or ``"-x"`` end (upstream
    kindergarden 0.2.5's wiper has it at -x); ``origin`` is the body frame: ``"centre"`` (the
    bounding-box centre, as every other object) or ``"bottom"`` (the centre of the bottom face,
    upstream's wiper frame, so the observed ``z`` is the height of the surface it rests on).
    """
    hl, hw = float(p["handle_length"]), float(p["handle_width"])
    head_l, head_h, head_w = (
        float(p["head_length"]),
        float(p["head_height"]),
        float(p["head_width"]),
    )
    if p["head_side"] not in ("+x", "-x"):
        raise ValueError(f"wiper {name!r}: head_side must be '+x' or '-x', got {p['head_side']!r}")
    if p["origin"] not in ("centre", "bottom"):
        raise ValueError(
            f"wiper {name!r}: origin must be 'centre' or 'bottom', got {p['origin']!r}"
        )
    sign = 1.0 if p["head_side"] == "+x" else -1.0
    parts = [
        _Box((sign * hl / 2, 0, head_h - hw / 2), (hl, hw, hw), p["handle_rgba"]),
        _Box((sign * (hl + head_w / 2), 0, head_h / 2), (head_w, head_l, head_h), p["head_rgba"]),
    ]
    if p["upright"]:
        parts = [
            _Box((0, 0, head_h / 2), (head_l, head_w, head_h), p["head_rgba"]),
            _Box((0, 0, head_h + hl / 2), (hw, hw, hl), p["handle_rgba"]),
        ]
    if p["origin"] == "centre":
        return _simple(name, parts, p["mass"], p["friction"])
    parts, size = _centred(parts)
    lift = float(size[2] / 2.0)  # bottom face at z = 0
    parts = [
        _Box(_vec3(np.array(q.centre) + np.array([0.0, 0.0, lift])), q.size, q.rgba, q.kind,
             q.euler, q.collide)
        for q in parts
    ]  # fmt: skip
    return ObjectAsset(_parts_xml(name, parts, p["mass"], p["friction"]), size, 0.0)


def _scoop(name: str, p: Params) -> ObjectAsset:
    """A scoop: an open cup (``cup_size`` outside, its floor and walls ``wall`` thick) with a
    handle sticking out along -x at rim height.

    ``open_front`` leaves out the cup's +x wall (upstream kindergarden 0.2.5's scoop, a
    dustpan-like cup open opposite its handle). ``origin`` is the body frame: ``"centre"`` (the
    bounding-box centre) or ``"back"`` (the middle of the cup's back bottom edge, where the
    handle meets it: upstream's scoop frame)."""
    cx, cy, cz = (float(v) for v in p["cup_size"])
    hx, hy, hz = (float(v) for v in p["handle_size"])
    parts = _open_box((cx, cy, cz), float(p["wall"]), p["rgba"])
    if p["open_front"]:
        del parts[1]  # the wall at +x
    parts.append(_Box((-cx / 2 - hx / 2, 0, cz - hz / 2), (hx, hy, hz), p["handle_rgba"]))
    if p["origin"] == "centre":
        return _simple(name, parts, p["mass"], p["friction"])
    if p["origin"] != "back":
        raise ValueError(f"scoop {name!r}: origin must be 'centre' or 'back', got {p['origin']!r}")
    moved = [
        _Box(_vec3(np.array(q.centre) + np.array([cx / 2, 0.0, 0.0])), q.size, q.rgba, q.kind,
             q.euler, q.collide)
        for q in parts
    ]  # fmt: skip
    lo, hi = _bbox(moved)
    return ObjectAsset(_parts_xml(name, moved, p["mass"], p["friction"]), hi - lo, 0.0)


def _seesaw(name: str, p: Params) -> ObjectAsset:
    """A seesaw: a pivot block and a beam on a hinge about y at the pivot's top, with stiffness,
    damping, friction loss and a range.

    ``base_plate`` (default true) stands the pivot on a plate (``base_size``) that keeps it from
    tipping over when the beam is loaded off-centre; upstream kindergarden 0.2.5's seesaw has
    none (its pivot is a triangular prism with the block's 3.5 cm x 7 cm footprint on the floor).
    ``origin`` is the body frame: ``"pivot"`` (the pivot block's centre) or ``"bottom"`` (the
    centre of the seesaw's bottom face, upstream's frame)."""
    bl, bw, bt = (float(v) for v in p["beam_size"])
    pw, ph = float(p["pivot_width"]), float(p["pivot_height"])
    plx, ply, plt = (float(v) for v in p["base_size"])
    if not p["base_plate"]:
        plx, ply, plt = 0.0, 0.0, 0.0
    if p["origin"] not in ("pivot", "bottom"):
        raise ValueError(
            f"seesaw {name!r}: origin must be 'pivot' or 'bottom', got {p['origin']!r}"
        )
    z0 = ph / 2 + plt if p["origin"] == "bottom" else 0.0  # the pivot block's centre
    clear = float(p["beam_clearance"])
    density = p["pivot_mass"] / (pw * bw * ph + plx * ply * plt)
    beam_density = p["beam_mass"] / (bl * bw * bt)
    geoms = [
        _geom("box", (pw / 2, bw / 2, ph / 2), (0, 0, z0), p["pivot_rgba"], OBJECT_CLASS,
              density=density, friction=p["pivot_friction"], name=f"{name}_pivot"),
    ]  # fmt: skip
    if plt > 0:
        geoms.append(
            _geom("box", (plx / 2, ply / 2, plt / 2), (0, 0, z0 - ph / 2 - plt / 2),
                  p["pivot_rgba"], OBJECT_CLASS, density=density, friction=p["pivot_friction"],
                  name=f"{name}_base")
        )  # fmt: skip
    lo, hi = (float(v) for v in p["hinge_range"])
    beam_z = ph / 2 + clear + bt / 2
    top = z0 + ph / 2
    children = (
        f'<body name="{name}_beam" pos="0 0 {top:.6g}">\n'
        f'<joint name="{name}_hinge" type="hinge" axis="0 1 0" range="{lo:.6g} {hi:.6g}" '
        f'stiffness="{p["hinge_stiffness"]:.6g}" damping="{p["damping"]:.6g}" '
        f'frictionloss="{p["hinge_frictionloss"]:.6g}" armature="0.0001"/>\n'
        + _geom(
            "box", (bl / 2, bw / 2, bt / 2), (0, 0, beam_z - ph / 2), p["beam_rgba"],
            OBJECT_CLASS, density=beam_density, friction=p["beam_friction"], name=f"{name}_beam_g",
        )
        + "\n</body>"
    )  # fmt: skip
    bbox = np.array([max(bl, plx), max(bw, ply), plt + ph + clear + bt])
    frames = {"beam": HingeFrame((0.0, 0.0, top), (0.0, 1.0, 0.0), (0.0, 0.0, clear + bt / 2))}
    bottom = 0.0 if p["origin"] == "bottom" else ph / 2 + plt
    return ObjectAsset("\n".join(geoms), bbox, bottom, children, f"{name}_hinge", frames)


#: Chair models (stand-ins for the three RoboCasa apartment chairs): seat width, depth, seat
#: height, backrest height above the floor, and whether it has armrests.
CHAIR_MODELS: dict[str, tuple[float, float, float, float, bool]] = {
    "apartment_chair_1": (0.70, 0.80, 0.42, 0.80, True),
    "apartment_chair_4": (0.50, 0.55, 0.46, 0.90, False),
    "apartment_chair_5": (0.60, 0.55, 0.46, 0.90, False),
}


def _chair(name: str, p: Params) -> ObjectAsset:
    """A chair stand-in. ``origin_height`` (m) puts the body frame that far above the floor when
    the chair stands (upstream kindergarden 0.2.5 observes its mesh chairs' frame, -0.203 m for
    the armchair); ``None`` puts it at the bounding box's centre."""
    w, dpt, seat_h, back_h, arms = CHAIR_MODELS[p["model"]]
    leg = 0.04
    seat_t = 0.05
    rgba, frame_rgba = p["rgba"], p["frame_rgba"]
    parts = [_Box((0, 0, seat_h - seat_t / 2), (w, dpt, seat_t), rgba)]
    for sx in (-1, 1):
        for sy in (-1, 1):
            # Capsule legs: one floor contact each (box feet would give four).
            parts.append(
                _Box(
                    (sx * (w / 2 - leg / 2), sy * (dpt / 2 - leg / 2), (seat_h - seat_t) / 2),
                    (leg, leg, seat_h - seat_t - leg),
                    frame_rgba,
                    "capsule",
                )
            )
    parts.append(
        _Box((0, -dpt / 2 + 0.03, (seat_h + back_h) / 2), (w, 0.06, back_h - seat_h), rgba)
    )
    if arms:
        for sx in (-1, 1):
            parts.append(
                _Box((sx * (w / 2 - 0.04), 0.0, seat_h + 0.15), (0.08, dpt * 0.8, 0.06), rgba)
            )
    if p["origin_height"] is None:
        return _simple(name, parts, p["mass"], p["friction"])
    lo, hi = _bbox(parts)
    height = float(p["origin_height"])
    shift = np.array([(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, lo[2] + height])
    moved = [
        _Box(_vec3(np.array(q.centre) - shift), q.size, q.rgba, q.kind, q.euler, q.collide)
        for q in parts
    ]
    return ObjectAsset(_parts_xml(name, moved, p["mass"], p["friction"]), hi - lo, height)


_FRICTION = [1.0, 0.005, 0.0001]
_RED = [0.5, 0.1, 0.1, 1.0]

#: Object type → (generator, parameter defaults). ``None`` defaults mean "derived".
OBJECT_TYPES: dict[str, tuple[Callable[[str, Params], ObjectAsset], Params]] = {
    "cube": (_cube, {"size": 0.02, "mass": None, "rgba": _RED, "friction": _FRICTION}),
    "cuboid": (
        _cuboid,
        {"size": [0.02, 0.02, 0.02], "mass": None, "rgba": _RED, "friction": _FRICTION},
    ),
    "bin": (
        _bin,
        {"size": [0.3, 0.3, 0.1], "wall": 0.01, "mass": 0.5, "rgba": [0.8, 0.8, 0.0, 1.0],
         "friction": _FRICTION, "origin": "centre"},
    ),
    "bowl": (
        _bowl,
        {"diameter": 0.12, "height": 0.05, "wall": 0.005, "segments": 16, "mass": 0.25,
         "rgba": [0.85, 0.85, 0.9, 1.0], "friction": _FRICTION, "origin": "centre"},
    ),
    "drink_box": (
        _drink_box,
        {"size": [0.05, 0.035, 0.11], "mass": 0.2, "rgba": [0.95, 0.55, 0.1, 1.0],
         "label_rgba": [0.2, 0.5, 0.2, 1.0], "friction": _FRICTION},
    ),
    "can": (
        _can,
        {"diameter": 0.066, "height": 0.12, "mass": 0.3, "rgba": [0.75, 0.75, 0.78, 1.0],
         "label_rgba": [0.8, 0.1, 0.1, 1.0], "friction": _FRICTION},
    ),
    "screw": (
        _screw,
        {"length": 0.045, "head_diameter": 0.018, "head_length": 0.008, "shaft_diameter": 0.009,
         "mass": 0.02, "rgba": [0.6, 0.6, 0.65, 1.0], "friction": _FRICTION,
         "solref": [0.004, 1.0]},
    ),
    "wiper": (
        _wiper,
        {"handle_length": 0.3, "handle_width": 0.02, "head_length": 0.3, "head_height": 0.04,
         "head_width": 0.03, "mass": 0.3, "handle_rgba": [0.9, 0.9, 0.9, 1.0],
         "head_rgba": [0.1, 0.1, 0.1, 1.0], "friction": _FRICTION, "head_side": "+x",
         "origin": "centre", "upright": False},
    ),
    "scoop": (
        _scoop,
        {"cup_size": [0.05, 0.05, 0.04], "wall": 0.002, "handle_size": [0.035, 0.02, 0.02],
         "mass": 0.05, "rgba": [0.3, 0.3, 0.8, 1.0], "handle_rgba": [0.2, 0.2, 0.2, 1.0],
         "friction": _FRICTION, "open_front": False, "origin": "centre"},
    ),
    "seesaw": (
        _seesaw,
        {"beam_size": [0.36, 0.07, 0.01], "beam_clearance": 0.0025, "pivot_height": 0.04,
         "base_size": [0.24, 0.12, 0.006], "base_plate": True, "origin": "pivot",
         "pivot_width": 0.035, "beam_mass": 0.1, "pivot_mass": 0.18, "damping": 0.02,
         "hinge_frictionloss": 0.03, "hinge_stiffness": 1.2, "hinge_range": [-0.7, 0.7],
         "beam_friction": [1.8, 0.025, 0.002], "pivot_friction": [1.5, 0.025, 0.002],
         "beam_rgba": [0.6, 0.4, 0.2, 1.0], "pivot_rgba": [0.3, 0.3, 0.3, 1.0]},
    ),
    "chair": (
        _chair,
        {"model": "apartment_chair_4", "mass": 6.0, "rgba": [0.55, 0.35, 0.2, 1.0],
         "frame_rgba": [0.2, 0.2, 0.2, 1.0], "friction": [0.6, 0.005, 0.0001],
         "origin_height": None},
    ),
}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# Fixtures


@dataclass(frozen=True)
class DrawerSpec:
    """A drawer of a cupboard cell: its body/joint names, closed frame and travel."""

    name: str
    joint: str
    frame: Array  # 4x4 region frame (drawer floor) in the fixture frame, drawer closed
    axis: tuple[float, float, float]
    travel: float


@dataclass
class FixtureAsset:
    """A generated fixture: geoms and drawer bodies, its local AABB, named region frames (4x4 in
    the fixture frame; ``drawer_of`` maps a frame name to the drawer that carries it)."""

    geoms: str
    children: str
    aabb: tuple[Array, Array]
    frames: dict[str, Array]
    drawers: list[DrawerSpec] = field(default_factory=list)
    drawer_of: dict[str, str] = field(default_factory=dict)
    default_frame: str = "top"
    #: Drawers welded shut (no joint): still observed, with a constant slide position of 0.
    welded_drawers: list[str] = field(default_factory=list)

    def body(self, name: str, pos: Sequence[float], quat: Sequence[float] | Array) -> str:
        return (
            f'<body name="{name}" mocap="true" pos="{_f(pos)}" quat="{_f(quat)}">\n'
            f"{self.geoms}\n{self.children}\n</body>"
        )


def _fbox(name: str, centre: Sequence[float], size: Sequence[float], rgba: Sequence[float]) -> str:
    return _geom("box", [s / 2 for s in size], centre, rgba, FIXTURE_CLASS, name=name)


def _cupboard(name: str, p: Params) -> FixtureAsset:
    length, depth, t = float(p["length"]), float(p["depth"]), float(p["shelf_thickness"])
    heights = [float(h) for h in p["shelf_heights"]]
    leg_h = float(p["leg_height"])
    partitions = p["shelf_partitions"] or [[] for _ in heights]
    drawers_cfg = p["shelf_drawers"] or [[False] * (len(parts) + 1) for parts in partitions]
    if len(partitions) != len(heights) or len(drawers_cfg) != len(heights):
        raise ValueError(
            f"cupboard {name}: shelf_partitions and shelf_drawers need one entry per shelf level "
            f"({len(heights)}), got {len(partitions)} and {len(drawers_cfg)}"
        )
    rgba, top_rgba = p["rgba"], p["rgba_top"]
    lines: list[str] = []
    # Board k's top surface is at z[k]; level k is the space between boards k and k+1.
    z = [leg_h + t]
    for h in heights:
        z.append(z[-1] + h + t)
    for k, zk in enumerate(z):
        colour = top_rgba if k == len(z) - 1 else rgba
        lines.append(_fbox(f"{name}_board{k}", (0, 0, zk - t / 2), (length, depth, t), colour))
    total = z[-1]
    if leg_h > 0:
        for sx in (-1, 1):
            for sy in (-1, 1):
                lines.append(
                    _fbox(
                        f"{name}_leg{sx}{sy}",
                        (sx * (length / 2 - 0.02), sy * (depth / 2 - 0.02), leg_h / 2),
                        (0.04, 0.04, leg_h),
                        p["rgba_leg"],
                    )
                )
    if not p["side_and_back_open"]:
        wall_h = total - leg_h
        for sx in (-1, 1):
            lines.append(
                _fbox(f"{name}_side{sx}", (sx * (length / 2 - t / 2), 0, leg_h + wall_h / 2),
                      (t, depth, wall_h), rgba)
            )  # fmt: skip
        lines.append(
            _fbox(f"{name}_back", (0, -depth / 2 + t / 2, leg_h + wall_h / 2),
                  (length - 2 * t, t, wall_h), rgba)
        )  # fmt: skip
    frames: dict[str, Array] = {}
    for k, zk in enumerate(z):
        frames[f"shelf:{k}"] = pose_matrix((0.0, 0.0, zk), np.eye(3))
    frames["top"] = frames[f"shelf:{len(z) - 1}"]
    children: list[str] = []
    drawers: list[DrawerSpec] = []
    drawer_of: dict[str, str] = {}
    welded: list[str] = []
    inner = length / 2 - (0.0 if p["side_and_back_open"] else t)
    for k, level_parts in enumerate(partitions):
        xs = [float(x) for x in level_parts]
        for x in xs:
            lines.append(
                _fbox(f"{name}_part{k}_{x:+.3f}", (x, 0, z[k] + heights[k] / 2),
                      (t, depth, heights[k]), p["rgba_partition"])
            )  # fmt: skip
        bounds = [-inner, *xs, inner]
        if len(drawers_cfg[k]) != len(bounds) - 1:
            raise ValueError(
                f"cupboard {name}: shelf_drawers[{k}] needs {len(bounds) - 1} entries (one per "
                f"cell), got {len(drawers_cfg[k])}"
            )
        for c in range(len(bounds) - 1):
            x0 = bounds[c] + (t / 2 if c > 0 else 0.0)
            x1 = bounds[c + 1] - (t / 2 if c < len(bounds) - 2 else 0.0)
            xc = (x0 + x1) / 2
            key = f"shelf:{k}/partition:{c}"
            frames[key] = pose_matrix((xc, 0.0, z[k]), np.eye(3))
            working = p["working_drawers"] is None or [k, c] in p["working_drawers"]
            if drawers_cfg[k][c] and not working:
                # A drawer that never opens: the same shapes, welded to the fixture (no joint,
                # no state, and no contacts with the fixture to compute).
                spec, xml = _drawer(name, k, c, x1 - x0, depth, heights[k], t, p)
                lines.extend(_static_drawer_geoms(xml, (xc, 0.0, z[k])))
                welded.append(spec)
            elif drawers_cfg[k][c]:
                spec, xml = _drawer(name, k, c, x1 - x0, depth, heights[k], t, p)
                children.append(xml.replace("__POS__", _f((xc, 0.0, z[k]))))
                drawers.append(
                    DrawerSpec(
                        spec, f"{spec}_slide", pose_matrix((xc, 0.0, z[k] + 0.01), np.eye(3)),
                        (0.0, 1.0, 0.0), float(p["drawer_travel"]) * depth,
                    )
                )  # fmt: skip
                frames[key] = drawers[-1].frame
                drawer_of[key] = spec
    aabb = (np.array([-length / 2, -depth / 2, 0.0]), np.array([length / 2, depth / 2, total]))
    return FixtureAsset("\n".join(lines), "\n".join(children), aabb, frames, drawers, drawer_of,
                        welded_drawers=welded)  # fmt: skip


def _drawer(
    cupboard: str, k: int, c: int, width: float, depth: float, height: float, t: float, p: Params
) -> tuple[str, str]:
    """A drawer filling one cell: a floor (1 cm), side and back walls, a face and a handle bar.
    Its body origin is the cell's floor centre; it slides along +y (out of the front). Named
    ``<cupboard>_drawer_s<level>c<cell>`` as upstream kindergarden 0.2.5."""
    name = f"{cupboard}_drawer_s{k}c{c}"
    gap = 0.004
    w = width - 2 * gap
    dd = depth - 0.02
    h = height - 2 * gap
    wall, floor = 0.01, 0.01
    yc = depth / 2 - 0.01 - dd / 2  # drawer box centre (face at the cupboard front)
    cls = OBJECT_CLASS
    fr, wr, face, handle = (
        p["rgba_drawer"],
        p["rgba_drawer"],
        p["rgba_drawer_face"],
        p["rgba_drawer_handle"],
    )
    mass = float(p["drawer_mass"])
    vol = w * dd * floor + 2 * dd * h * wall + w * h * wall + w * (h + 2 * gap) * 0.02
    dens = mass / vol
    z_mid = gap + h / 2
    boxes = [  # (half extents, centre, colour)
        ((w / 2, dd / 2, floor / 2), (0, yc, gap + floor / 2), fr),
        ((wall / 2, dd / 2, h / 2), (-w / 2 + wall / 2, yc, z_mid), wr),
        ((wall / 2, dd / 2, h / 2), (w / 2 - wall / 2, yc, z_mid), wr),
        ((w / 2, wall / 2, h / 2), (0, yc - dd / 2 + wall / 2, z_mid), wr),
        ((w / 2, 0.01, (h + gap) / 2), (0, depth / 2, z_mid), face),
        ((0.06, 0.0075, 0.0075), (0, depth / 2 + 0.045, z_mid), handle),
        ((0.0075, 0.0175, 0.0075), (-0.0525, depth / 2 + 0.0275, z_mid), handle),
        ((0.0075, 0.0175, 0.0075), (0.0525, depth / 2 + 0.0275, z_mid), handle),
    ]
    g = [_geom("box", half, c, rgba, cls, density=dens) for half, c, rgba in boxes]
    travel = float(p["drawer_travel"]) * depth
    xml = (
        f'<body name="{name}" pos="__POS__">\n'
        f'<joint name="{name}_slide" type="slide" axis="0 1 0" range="0 {travel:.6g}" '
        f'damping="{p["drawer_damping"]:.6g}" frictionloss="{p["drawer_frictionloss"]:.6g}" '
        f'armature="0.01"/>\n' + "\n".join(g) + "\n</body>"
    )
    del t
    return name, xml


def _static_drawer_geoms(xml: str, offset: Sequence[float]) -> list[str]:
    """The geoms of a drawer body, moved into the fixture frame as fixture geoms."""
    out = []
    for line in xml.splitlines():
        if not line.startswith("<geom"):
            continue
        pos = re.search(r'pos="([^"]*)"', line)
        assert pos is not None
        local = np.array([float(v) for v in pos.group(1).split()]) + np.asarray(offset)
        line = line[: pos.start(1)] + _f(local) + line[pos.end(1) :]
        line = line.replace(f'class="{OBJECT_CLASS}"', f'class="{FIXTURE_CLASS}"')
        out.append(re.sub(r' density="[^"]*"', "", line))
    return out


def _table(name: str, p: Params) -> FixtureAsset:
    length, width, height, t = (float(p[k]) for k in ("length", "width", "height", "thickness"))
    leg = float(p["leg_size"])
    lines = [_fbox(f"{name}_top", (0, 0, height - t / 2), (length, width, t), p["rgba"])]
    for sx in (-1, 1):
        for sy in (-1, 1):
            lines.append(
                _fbox(
                    f"{name}_leg{sx}{sy}",
                    (sx * (length / 2 - leg), sy * (width / 2 - leg), (height - t) / 2),
                    (leg, leg, height - t),
                    p["rgba_leg"],
                )
            )
    aabb = (np.array([-length / 2, -width / 2, 0.0]), np.array([length / 2, width / 2, height]))
    frames = {"top": pose_matrix((0.0, 0.0, height), np.eye(3))}
    return FixtureAsset("\n".join(lines), "", aabb, frames)


def _fixed_box(name: str, p: Params) -> FixtureAsset:
    sx, sy, sz = (float(v) for v in p["size"])
    lines = [_fbox(f"{name}_box", (0, 0, sz / 2), (sx, sy, sz), p["rgba"])]
    aabb = (np.array([-sx / 2, -sy / 2, 0.0]), np.array([sx / 2, sy / 2, sz]))
    return FixtureAsset("\n".join(lines), "", aabb, {"top": pose_matrix((0, 0, sz), np.eye(3))})


FIXTURE_TYPES: dict[str, tuple[Callable[[str, Params], FixtureAsset], Params]] = {
    "cupboard": (
        _cupboard,
        {"length": 0.6, "depth": 0.3, "shelf_heights": [0.25], "shelf_thickness": 0.02,
         "shelf_partitions": None, "shelf_drawers": None, "side_and_back_open": False,
         "leg_height": 0.0, "rgba": list(WOOD), "rgba_top": list(WOOD), "rgba_leg": list(WOOD),
         "rgba_partition": list(WOOD), "rgba_drawer": list(WOOD),
         "rgba_drawer_face": list(DRAWER_FACE), "rgba_drawer_handle": list(BLACK),
         "drawer_mass": 1.0, "drawer_travel": 0.8, "drawer_damping": 5.0,
         "drawer_frictionloss": 0.5, "working_drawers": None},
    ),
    "table": (
        _table,
        {"length": 1.2, "width": 0.6, "height": 0.4, "thickness": 0.03, "leg_size": 0.05,
         "rgba": [0.76, 0.6, 0.42, 1.0], "rgba_leg": [0.45, 0.35, 0.25, 1.0]},
    ),
    "fixed_box": (_fixed_box, {"size": [0.1, 0.1, 0.1], "rgba": list(DRAWER_FACE)}),
}  # fmt: skip

#: Fixture types observed with a bounding box (the "static collider" type of the spec).
STATIC_COLLIDER_TYPES = ("fixed_box",)


def build_object(kind: str, name: str, params: Params) -> ObjectAsset:
    """Generate a movable object of type ``kind`` with (already validated) ``params``."""
    gen, defaults = OBJECT_TYPES[kind]
    return gen(name, {**defaults, **params})


def build_fixture(kind: str, name: str, params: Params) -> FixtureAsset:
    """Generate a fixture of type ``kind`` with (already validated) ``params``."""
    gen, defaults = FIXTURE_TYPES[kind]
    return gen(name, {**defaults, **params})
