"""The pybullet backend of the Kinematic3D families: one private DIRECT client per scene.

A :class:`PyBulletScene` holds the robot (loaded from the generated URDF), an invisible grasp
marker at the end effector, and one body per named object. Nothing is ever simulated: bodies are
teleported (``reset*``) and queried with ``getClosestPoints``, which is exact for boxes and
capsules and stateless, so results depend only on the poses that were set. Triangular prisms are
convex hulls, which pybullet inflates by a 1 mm margin; their hull vertices are shrunk by that
margin so distances stay exact on the faces.

No GUI, no global state: every call names this scene's client. ``close()`` disconnects; the scene
reconnects lazily if it is used again.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pybullet as pb
from numpy.typing import NDArray

from kinder_garden3d.kinematic3d.geometry import Part, quat_to_matrix
from kinder_garden3d.robot.description import (
    PINCH_OFFSET,
    finger_joint_positions,
    robot_description,
    rpy_to_matrix,
)
from kinder_garden3d.robot.urdf import urdf_path

Array = NDArray[np.float64]
Rgba = tuple[float, float, float, float]

#: Half extents of the invisible grasp-detection box at the end effector (z = approach axis).
MARKER_HALF = (0.01, 0.01, 0.035)
#: The end-effector ("tool") frame sits this far out of the Gen3 flange along the approach axis,
#: with the flange's orientation: the ``tool_frame`` of the Kinova URDF that upstream's
#: pybullet robot uses (its gripper, like ours, is mounted a quarter turn about the approach axis,
#: so the tool frame's x axis is the gripper's closing direction).
TOOL_OFFSET = 0.12
#: Quarter turn about z from the gripper frame back to the flange frame (x, y, z, w): the gripper
#: is the flange frame turned by −π/2 about z (URDF rpy (π, 0, π/2) from the bracelet = the
#: flange's roll π followed by −π/2 about the new z).
_GRIPPER_TO_FLANGE = (0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5))
#: Arm links checked against each other for self-collisions, in chain order, and the finger links
#: checked against all but the last of them. Neighbours in the chain are not checked (they touch
#: at their joint). This is the pair list of upstream's Gen3 + 2F-85 pybullet robot mapped onto
#: this model's links: it leaves out spherical_wrist_2 and the gripper housing.
SELF_COLLISION_ARM = (
    "shoulder_link",
    "half_arm_1_link",
    "half_arm_2_link",
    "forearm_link",
    "spherical_wrist_1_link",
    "bracelet_link",
)
SELF_COLLISION_FINGERS = ("left_finger_link", "right_finger_link")
_HULL_MARGIN = 0.001


@dataclass(frozen=True)
class BodySpec:
    """What a scene body looks like: convex parts, colour, and whether it collides."""

    parts: tuple[Part, ...]
    rgba: Rgba
    collide: bool = True
    sphere_radius: float = 0.0  # > 0: a visual-only sphere instead of parts


def _shrunk_prism(part: Part) -> list[list[float]]:
    tri = np.array(part.params[:6]).reshape(3, 2)
    hd = part.params[6]
    lengths = np.linalg.norm(np.roll(tri, -1, axis=0) - tri, axis=1)
    # Incentre: vertices weighted by the lengths of the opposite sides.
    opposite = np.roll(lengths, -1)
    centre = (tri * opposite[:, None]).sum(axis=0) / opposite.sum()
    area = 0.5 * abs(
        (tri[1, 0] - tri[0, 0]) * (tri[2, 1] - tri[0, 1])
        - (tri[2, 0] - tri[0, 0]) * (tri[1, 1] - tri[0, 1])
    )
    inradius = 2.0 * area / lengths.sum()
    scale = (inradius - _HULL_MARGIN) / inradius
    shrunk = centre + (tri - centre) * scale
    hd_in = hd - _HULL_MARGIN
    return [[float(x), float(y), z] for z in (-hd_in, hd_in) for x, y in shrunk]


def _prism_mesh(part: Part) -> tuple[list[list[float]], list[int]]:
    tri = np.array(part.params[:6]).reshape(3, 2)
    hd = part.params[6]
    verts = [[float(x), float(y), z] for z in (-hd, hd) for x, y in tri]
    # Counter-clockwise triangles seen from outside (bottom 0-2, top 3-5).
    ccw = (tri[1, 0] - tri[0, 0]) * (tri[2, 1] - tri[0, 1]) - (tri[2, 0] - tri[0, 0]) * (
        tri[1, 1] - tri[0, 1]
    ) > 0
    a, b = (1, 2) if ccw else (2, 1)
    idx = [0, b, a, 3, 3 + a, 3 + b]
    for i in range(3):
        j = (i + 1) % 3 if ccw else (i + 2) % 3
        idx += [i, j, 3 + j, i, 3 + j, 3 + i]
    return verts, idx


class PyBulletScene:
    """A private pybullet DIRECT client holding the robot and the objects of one env."""

    def __init__(self, base_z: float = 0.0) -> None:
        self.base_z = base_z
        self._client: int | None = None
        self._bodies: dict[str, tuple[BodySpec, int]] = {}
        self._desc = robot_description()
        self.robot = -1
        self.marker = -1
        self._arm_idx: list[int] = []
        self._finger_idx: list[int] = []
        self._finger_links: list[int] = []
        self._self_pairs: list[tuple[int, int]] = []
        self._link_idx: dict[str, int] = {}
        #: Incremented on every (re)connection, so callers can tell a fresh client apart.
        self.generation = 0

    # -- connection -----------------------------------------------------------------------------
    @property
    def client(self) -> int:
        """The pybullet client id (connecting on first use)."""
        if self._client is None:
            self._connect()
        assert self._client is not None
        return self._client

    def _connect(self) -> None:
        cid = pb.connect(pb.DIRECT)
        if cid < 0:
            raise RuntimeError("pybullet could not open a DIRECT client")
        self._client = cid
        self.generation += 1
        self._bodies = {}
        self.robot = pb.loadURDF(
            str(urdf_path()),
            basePosition=[0.0, 0.0, self.base_z],
            useFixedBase=True,
            physicsClientId=cid,
        )
        for i in range(pb.getNumJoints(self.robot, physicsClientId=cid)):
            info = pb.getJointInfo(self.robot, i, physicsClientId=cid)
            self._link_idx[info[12].decode()] = i
            joint_name = info[1].decode()
            if joint_name in self._desc.arm_joint_names:
                self._arm_idx.append(i)
            if joint_name in self._desc.finger_joint_names:
                self._finger_idx.append(i)
        self._finger_links = list(self._finger_idx)
        arm = SELF_COLLISION_ARM
        pairs = [(arm[i], arm[j]) for i in range(len(arm)) for j in range(i + 2, len(arm))]
        pairs += [(a, f) for a in arm[:-1] for f in SELF_COLLISION_FINGERS]
        self._self_pairs = [(self._link_idx[a], self._link_idx[b]) for a, b in pairs]
        marker_shape = pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=list(MARKER_HALF), physicsClientId=cid
        )
        self.marker = pb.createMultiBody(0.0, marker_shape, -1, physicsClientId=cid)

    def close(self) -> None:
        """Disconnect the client (idempotent)."""
        if self._client is not None:
            with contextlib.suppress(pb.error):
                pb.disconnect(physicsClientId=self._client)
            self._client = None
            self._bodies = {}
            self._arm_idx, self._finger_idx, self._finger_links = [], [], []
            self._link_idx = {}

    def __del__(self) -> None:
        with contextlib.suppress(Exception):  # at interpreter shutdown pybullet may be gone
            self.close()

    # -- bodies ---------------------------------------------------------------------------------
    def _create_body(self, spec: BodySpec) -> int:
        cid = self.client
        if spec.sphere_radius > 0:
            vis = pb.createVisualShape(
                pb.GEOM_SPHERE, radius=spec.sphere_radius, rgbaColor=spec.rgba, physicsClientId=cid
            )
            return int(pb.createMultiBody(0.0, -1, vis, physicsClientId=cid))
        cols, viss = [], []
        for part in spec.parts:
            frame = list(part.pos)
            if part.kind == "box":
                col = (
                    pb.createCollisionShape(
                        pb.GEOM_BOX, halfExtents=list(part.params), collisionFramePosition=frame,
                        physicsClientId=cid,
                    )
                    if spec.collide
                    else -1
                )  # fmt: skip
                vis = pb.createVisualShape(
                    pb.GEOM_BOX, halfExtents=list(part.params), rgbaColor=spec.rgba,
                    visualFramePosition=frame, physicsClientId=cid,
                )  # fmt: skip
            elif part.kind == "cylinder":
                radius, height = part.params[0], 2.0 * part.params[1]
                col = (
                    pb.createCollisionShape(
                        pb.GEOM_CYLINDER, radius=radius, height=height,
                        collisionFramePosition=frame, physicsClientId=cid,
                    )
                    if spec.collide
                    else -1
                )  # fmt: skip
                vis = pb.createVisualShape(
                    pb.GEOM_CYLINDER, radius=radius, length=height, rgbaColor=spec.rgba,
                    visualFramePosition=frame, physicsClientId=cid,
                )  # fmt: skip
            else:
                hull = _shrunk_prism(part)
                col = (
                    pb.createCollisionShape(
                        pb.GEOM_MESH, vertices=hull, collisionFramePosition=frame,
                        physicsClientId=cid,
                    )
                    if spec.collide
                    else -1
                )  # fmt: skip
                verts, idx = _prism_mesh(part)
                vis = pb.createVisualShape(
                    pb.GEOM_MESH, vertices=verts, indices=idx, rgbaColor=spec.rgba,
                    visualFramePosition=frame, physicsClientId=cid,
                )  # fmt: skip
            cols.append(col)
            viss.append(vis)
        n = len(spec.parts) - 1
        # Extra parts are fixed links at the body origin; every part carries its own offset.
        body = pb.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=cols[0],
            baseVisualShapeIndex=viss[0],
            baseInertialFramePosition=[0.0, 0.0, 0.0],
            linkMasses=[0.0] * n,
            linkCollisionShapeIndices=cols[1:],
            linkVisualShapeIndices=viss[1:],
            linkPositions=[[0.0, 0.0, 0.0]] * n,
            linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
            linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n,
            linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
            linkParentIndices=[0] * n,
            linkJointTypes=[pb.JOINT_FIXED] * n,
            linkJointAxis=[[0.0, 0.0, 1.0]] * n,
            physicsClientId=cid,
        )
        return int(body)

    def ensure_body(self, name: str, spec: BodySpec) -> int:
        """The body for ``name``, (re)created if its spec changed."""
        current = self._bodies.get(name)
        if current is not None and current[0] == spec:
            return current[1]
        if current is not None:
            pb.removeBody(current[1], physicsClientId=self.client)
        body = self._create_body(spec)
        self._bodies[name] = (spec, body)
        return body

    def remove_except(self, keep: set[str]) -> None:
        """Remove the bodies whose names are not in ``keep``."""
        for name in [n for n in self._bodies if n not in keep]:
            pb.removeBody(self._bodies.pop(name)[1], physicsClientId=self.client)

    def body(self, name: str) -> int:
        """The body id of a named object."""
        return self._bodies[name][1]

    def set_pose(self, name: str, pos: Array | list[float], quat: Array | list[float]) -> None:
        """Teleport a named object."""
        pb.resetBasePositionAndOrientation(
            self._bodies[name][1], list(pos), list(quat), physicsClientId=self.client
        )

    # -- robot ----------------------------------------------------------------------------------
    def set_robot(self, config: Array, finger_state: float | None = None) -> None:
        """Set base (x, y, yaw) and the 7 joints from a 10-vector; optionally the fingers."""
        cid = self.client
        yaw = float(config[2])
        pb.resetBasePositionAndOrientation(
            self.robot,
            [float(config[0]), float(config[1]), self.base_z],
            [0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)],
            physicsClientId=cid,
        )
        if finger_state is None:
            pb.resetJointStatesMultiDof(
                self.robot,
                self._arm_idx,
                [[float(q)] for q in config[3:10]],
                physicsClientId=cid,
            )
        else:
            left, right = finger_joint_positions(finger_state)
            pb.resetJointStatesMultiDof(
                self.robot,
                self._arm_idx + self._finger_idx,
                [[float(q)] for q in config[3:10]] + [[left], [right]],
                physicsClientId=cid,
            )

    def ee_pose(self) -> tuple[Array, Array]:
        """World pose of the end effector: the tool frame (see :data:`TOOL_OFFSET`; z =
        approach, x = closing direction)."""
        state = pb.getLinkState(
            self.robot,
            self._link_idx["gripper_base_link"],
            computeForwardKinematics=True,
            physicsClientId=self.client,
        )
        pos, quat = np.array(state[4]), np.array(state[5])
        _, flange_q = pb.multiplyTransforms(
            [0.0, 0.0, 0.0], quat.tolist(), [0.0, 0.0, 0.0], list(_GRIPPER_TO_FLANGE)
        )
        return pos + quat_to_matrix(quat)[:, 2] * TOOL_OFFSET, np.array(flange_q)

    def pinch_pose(self) -> tuple[Array, Array]:
        """World pose of the pinch point between the pads (z = approach, y = closing)."""
        pos, quat = self.link_pose("gripper_base_link")
        return pos + quat_to_matrix(quat)[:, 2] * PINCH_OFFSET, quat

    def place_marker(self) -> None:
        """Move the grasp marker to the end effector."""
        pos, quat = self.ee_pose()
        pb.resetBasePositionAndOrientation(
            self.marker, pos.tolist(), quat.tolist(), physicsClientId=self.client
        )

    def link_pose(self, link: str) -> tuple[Array, Array]:
        """World pose of a robot link."""
        if link == "base_link":
            pos, quat = pb.getBasePositionAndOrientation(self.robot, physicsClientId=self.client)
            return np.array(pos), np.array(quat)
        state = pb.getLinkState(
            self.robot,
            self._link_idx[link],
            computeForwardKinematics=True,
            physicsClientId=self.client,
        )
        return np.array(state[4]), np.array(state[5])

    # -- queries --------------------------------------------------------------------------------
    def min_distance(self, body_a: int, body_b: int, max_distance: float = 0.0) -> float:
        """Smallest signed distance between two bodies, or +inf if above ``max_distance``."""
        pts = pb.getClosestPoints(body_a, body_b, max_distance, physicsClientId=self.client)
        if not pts:
            return math.inf
        return float(min(p[8] for p in pts))

    def collides(self, body_a: int, bodies: list[int], tolerance: float) -> bool:
        """Whether ``body_a`` penetrates any of ``bodies`` deeper than ``tolerance``."""
        cid = self.client
        for b in bodies:
            pts = pb.getClosestPoints(body_a, b, -tolerance, physicsClientId=cid)
            if pts:
                return True
        return False

    def marker_touching(self, bodies: list[int], distance: float) -> list[int]:
        """The bodies within ``distance`` of the grasp marker."""
        cid = self.client
        return [
            b for b in bodies if pb.getClosestPoints(self.marker, b, distance, physicsClientId=cid)
        ]

    def near(self, body_a: int, body_b: int, distance: float) -> bool:
        """Whether two bodies come within ``distance`` of each other (touching included)."""
        return bool(pb.getClosestPoints(body_a, body_b, distance, physicsClientId=self.client))

    def arm_near(self, bodies: list[int], distance: float, include_base: bool = False) -> bool:
        """Whether a robot link comes within ``distance`` of any of ``bodies``; the base chassis
        (pybullet's root link, index −1) counts only with ``include_base``."""
        cid = self.client
        for b in bodies:
            pts = pb.getClosestPoints(self.robot, b, distance, physicsClientId=cid)
            if any(include_base or p[3] != -1 for p in pts):
                return True
        return False

    def self_collides(self, distance: float) -> bool:
        """Whether any checked pair of robot links (see :data:`SELF_COLLISION_ARM`) comes within
        ``distance`` of each other."""
        cid, robot = self.client, self.robot
        return any(
            pb.getClosestPoints(
                robot, robot, distance, linkIndexA=a, linkIndexB=b, physicsClientId=cid
            )
            for a, b in self._self_pairs
        )

    def support_gap(self, body: int, surface: int, max_gap: float) -> float:
        """The vertical gap from ``body`` down to ``surface`` (+inf if not below within range).

        A contact counts as support when the surface lies beneath the body (contact normal
        pointing mostly up from the surface to the body).
        """
        pts = pb.getClosestPoints(body, surface, max_gap, physicsClientId=self.client)
        gaps = [p[8] for p in pts if p[7][2] > 0.7]  # normal on B, pointing from B to A
        return float(min(gaps)) if gaps else math.inf

    # -- cameras --------------------------------------------------------------------------------
    def robot_camera(self, name: str) -> tuple[Array, Array, Array, float]:
        """(eye, target, up, fovy) of a robot-mounted camera."""
        cam = self._desc.camera(name)
        pos, quat = self.link_pose(cam.link)
        rot = quat_to_matrix(quat) @ rpy_to_matrix(cam.rpy)
        eye = pos + quat_to_matrix(quat) @ np.array(cam.pos)
        return eye, eye - rot[:, 2], rot[:, 1], cam.fovy

    def capture_orbit(
        self,
        target: tuple[float, float, float],
        distance: float,
        yaw: float,
        pitch: float,
        width: int,
        height: int,
        fovy: float = 60.0,
    ) -> NDArray[np.uint8]:
        """Render from an orbit camera (pybullet's yaw/pitch convention, degrees)."""
        view = pb.computeViewMatrixFromYawPitchRoll(
            list(target), distance, yaw, pitch, 0.0, 2, physicsClientId=self.client
        )
        return self._render(view, fovy, width, height)

    def capture(
        self,
        eye: Array,
        target: Array,
        up: Array,
        fovy: float,
        width: int,
        height: int,
    ) -> NDArray[np.uint8]:
        """Render an RGB image with pybullet's CPU (TinyRenderer) rasteriser."""
        view = pb.computeViewMatrix(
            eye.tolist(), target.tolist(), up.tolist(), physicsClientId=self.client
        )
        return self._render(view, fovy, width, height)

    def _render(self, view: Any, fovy: float, width: int, height: int) -> NDArray[np.uint8]:
        cid = self.client
        proj = pb.computeProjectionMatrixFOV(fovy, width / height, 0.01, 20.0, physicsClientId=cid)
        out: Any = pb.getCameraImage(
            width,
            height,
            view,
            proj,
            renderer=pb.ER_TINY_RENDERER,
            flags=pb.ER_NO_SEGMENTATION_MASK,
            shadow=0,
            lightDirection=[0.4, -0.3, 1.0],
            physicsClientId=cid,
        )
        rgba = np.asarray(out[2], dtype=np.uint8).reshape(height, width, 4)
        return np.ascontiguousarray(rgba[:, :, :3])


class BoxProbe:
    """Contact tests between axis-aligned boxes with pybullet's own closest-point query, in a
    private DIRECT client (connected on first use).

    Resets that must reproduce upstream's rejection sampling ask pybullet whether two boxes
    touch, as upstream does: pybullet misses penetrations shallower than about 0.1 mm between
    boxes, so an exact geometric test would reject draws that upstream keeps.
    """

    def __init__(self) -> None:
        self._client: int | None = None
        self._bodies: dict[tuple[float, float, float], list[int]] = {}

    def _body(self, half: tuple[float, float, float], slot: int) -> int:
        if self._client is None:
            cid = pb.connect(pb.DIRECT)
            if cid < 0:
                raise RuntimeError("pybullet could not open a DIRECT client")
            self._client = cid
        bodies = self._bodies.setdefault(half, [])
        while len(bodies) <= slot:
            shape = pb.createCollisionShape(
                pb.GEOM_BOX, halfExtents=list(half), physicsClientId=self._client
            )
            bodies.append(pb.createMultiBody(0.0, shape, -1, physicsClientId=self._client))
        return bodies[slot]

    def touch(self, c1: Array, h1: Array, c2: Array, h2: Array, distance: float) -> bool:
        """Whether boxes (centre, half extents) come within ``distance`` by pybullet's query."""
        k1 = (float(h1[0]), float(h1[1]), float(h1[2]))
        k2 = (float(h2[0]), float(h2[1]), float(h2[2]))
        a = self._body(k1, 0)
        b = self._body(k2, 1 if k2 == k1 else 0)
        cid = self._client
        pb.resetBasePositionAndOrientation(
            a, [float(v) for v in c1], [0, 0, 0, 1], physicsClientId=cid
        )
        pb.resetBasePositionAndOrientation(
            b, [float(v) for v in c2], [0, 0, 0, 1], physicsClientId=cid
        )
        return bool(pb.getClosestPoints(a, b, distance, physicsClientId=cid))

    def place_boxes(
        self,
        rng: np.random.Generator,
        count: int,
        region: tuple[float, float, float, float],
        half: Array,
        obstacles: list[tuple[Array, Array]],
        distance: float,
        attempts: int,
    ) -> list[Array] | None:
        """Upstream's floor rejection sampler, draw for draw: ``count`` boxes of half extents
        ``half`` in turn, each centre uniform over ``region`` (x0, x1, y0, y1) at height
        ``half[2]``, a draw rejected when it comes within ``distance`` of an obstacle or a box
        placed before; None when a box finds no place in ``attempts`` draws."""
        x0, x1, y0, y1 = region
        low, high = (x0, y0, half[2]), (x1, y1, half[2])
        placed = list(obstacles)
        centres: list[Array] = []
        for _ in range(count):
            for _ in range(attempts):
                c = np.asarray(rng.uniform(low, high), dtype=np.float64)
                if not any(self.touch(c, half, oc, oh, distance) for oc, oh in placed):
                    break
            else:
                return None
            placed.append((c, half))
            centres.append(c)
        return centres

    def close(self) -> None:
        """Disconnect the client (idempotent)."""
        if self._client is not None:
            with contextlib.suppress(pb.error):
                pb.disconnect(physicsClientId=self._client)
            self._client = None
            self._bodies = {}

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()
