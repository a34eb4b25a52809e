"""Scene assembly: a task's fixtures, objects, regions, cameras and the shared robot as one MJCF
string (no MuJoCo import here; the env compiles the string once per construction).

The robot comes from :func:`kinder_garden3d.robot.mjcf.mjcf_parts` (prefix ``robot_``). Two
changes are made while splicing it in, both in this module and not in ``robot/``:

* the seven arm torque motors are replaced by position actuators with the spec's PD gains
  (``force = Kp (q* - q) - Kd q̇``, clipped to the motor limits), so the PD runs inside MuJoCo
  at every physics tick instead of in Python;
* the arm and gripper bodies get ``gravcomp="1"``: MuJoCo applies the gravity-compensation
  torque (the gravity part of the spec's ``qfrc_bias`` term) as a passive force.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from kinder_garden3d.dynamic3d.assets import (
    DEFAULT_CLASSES,
    FIXTURE_CLASS,
    FixtureAsset,
    HingeFrame,
    ObjectAsset,
    build_fixture,
    build_object,
)
from kinder_garden3d.dynamic3d.geometry import (
    Array,
    look_at_xyaxes,
    pose_matrix,
    quat_mul,
    yaw_quat,
)
from kinder_garden3d.dynamic3d.taskfile import GROUND, TaskFileError, TaskSpec
from kinder_garden3d.robot.description import robot_description
from kinder_garden3d.robot.fr3 import fr3_mjcf_parts
from kinder_garden3d.robot.mjcf import ARM_TORQUE_LIMITS, mjcf_parts

ROBOT_PREFIX = "robot_"
#: Arm PD gains of the spec (N m / rad and N m s / rad).
ARM_KP = (200.0, 200.0, 200.0, 200.0, 100.0, 100.0, 100.0)
ARM_KD = (30.0, 30.0, 30.0, 30.0, 15.0, 15.0, 15.0)
#: Passive damping of upstream kindergarden 0.2.5's arm joints (N m s/rad), used with the
#: held-torque arm control.
UPSTREAM_ARM_DAMPING = (50.0, 50.0, 50.0, 50.0, 25.0, 25.0, 25.0)
#: Robot bodies that receive gravity compensation (everything carried by the arm).
_GRAVCOMP_BODIES = (
    "gen3_base_link", "shoulder_link", "half_arm_1_link", "half_arm_2_link", "forearm_link",
    "spherical_wrist_1_link", "spherical_wrist_2_link", "bracelet_link", "gripper_base_link",
    "left_finger_link", "right_finger_link",
)  # fmt: skip


@dataclass(frozen=True)
class RegionFrame:
    """How to find a region's frame from a state.

    ``kind``: ``"ground"`` (world frame), ``"fixture"`` or ``"object"`` (the target's pose).
    ``local``: a constant 4x4 transform in the target frame. ``drawer``: the drawer object that
    carries the frame (translated by its slide position along ``drawer_axis``). ``hinge``: a
    hinged frame of the target (the seesaw's beam), rotated by the target's hinge angle.
    """

    kind: str
    target: str
    local: Array
    align: str
    drawer: str | None = None
    drawer_axis: tuple[float, float, float] = (0.0, 1.0, 0.0)
    hinge: HingeFrame | None = None


@dataclass
class Scene:
    """The compiled-to-be MJCF and what the env needs to know about its entities."""

    xml: str
    objects: dict[str, ObjectAsset]
    fixtures: dict[str, FixtureAsset]
    drawers: dict[str, tuple[str, str]]  # drawer object name -> (fixture, joint name)
    seesaws: dict[str, str]  # seesaw object -> hinge joint name
    regions: dict[str, RegionFrame]
    cameras: list[str]
    parked: dict[str, tuple[float, float, float]] = field(default_factory=dict)


def _f(values: object) -> str:
    return " ".join(f"{float(v):.6g}" for v in np.asarray(values, dtype=float).ravel())


def _axis_quat(axis: int, angle: float) -> Array:
    q = np.zeros(4)
    q[0] = math.cos(angle / 2)
    q[1 + axis] = math.sin(angle / 2)
    return q


def _robot_xml(arm_motors: bool = False) -> tuple[str, str, str, str]:
    """The robot's worldbody, actuators, equality and defaults, adapted as described above.

    With ``arm_motors`` the arm keeps its torque motors and gets no ``gravcomp`` (the env then
    computes the PD torque with bias compensation itself, as upstream does)."""
    parts = mjcf_parts(prefix=ROBOT_PREFIX)
    body = parts.worldbody
    for name in () if arm_motors else _GRAVCOMP_BODIES:
        tag = f'<body name="{ROBOT_PREFIX}{name}"'
        if tag not in body:
            raise RuntimeError(f"robot MJCF has no body {ROBOT_PREFIX}{name}")
        body = body.replace(tag, f'{tag} gravcomp="1"')
    # The base camera's spec orientation is MuJoCo euler (0, -45°, -90°) (intrinsic x-y-z);
    # the robot model converts it as URDF roll-pitch-yaw, which turns the image. Re-orient it.
    cam = re.search(rf'<camera name="{ROBOT_PREFIX}base" [^>]*quat="([^"]*)"', body)
    if cam is None:
        raise RuntimeError(f"robot MJCF has no camera {ROBOT_PREFIX}base")
    fixed = quat_mul(quat_mul(_axis_quat(0, 0.0), _axis_quat(1, -math.pi / 4)),
                     _axis_quat(2, -math.pi / 2))  # fmt: skip
    body = body[: cam.start(1)] + _f(fixed) + body[cam.end(1) :]
    if arm_motors:
        # Upstream's arm joints: passive damping 50 (joints 1-4) and 25 N m s/rad, no armature.
        for i, joint in enumerate(robot_description().arm_joint_names):
            found = re.search(rf'<joint name="{ROBOT_PREFIX}{joint}"[^>]*>', body)
            if found is None:
                raise RuntimeError(f"robot MJCF has no joint {ROBOT_PREFIX}{joint}")
            new = re.sub(r'armature="[^"]*"', 'armature="0"', found.group(0))
            new = re.sub(r'damping="[^"]*"', f'damping="{UPSTREAM_ARM_DAMPING[i]:g}"', new)
            body = body[: found.start()] + new + body[found.end() :]
        return body, parts.actuator, parts.equality, parts.default
    lines = [ln for ln in parts.actuator.splitlines() if "<motor " not in ln]
    desc = robot_description()
    arm = []
    for i, joint in enumerate(desc.arm_joint_names):
        lim = ARM_TORQUE_LIMITS[i]
        arm.append(
            f'    <position name="{ROBOT_PREFIX}arm_{i + 1}" joint="{ROBOT_PREFIX}{joint}" '
            f'kp="{ARM_KP[i]:g}" kv="{ARM_KD[i]:g}" ctrllimited="false" '
            f'forcelimited="true" forcerange="{-lim:g} {lim:g}"/>'
        )
    if len(lines) + len(arm) != 3 + 7 + 1:
        raise RuntimeError("unexpected robot actuator layout (expected 3 base, 7 arm, 1 gripper)")
    actuators = "\n".join(lines[:3] + arm + lines[3:])
    return body, actuators, parts.equality, parts.default


def _fr3_robot_xml() -> tuple[str, str, str, str]:
    """The Franka FR3 arm (``robot/fr3.py``, prefix ``robot_``) with its mount body
    ``robot_fr3_link0`` made a mocap body, so that the mount pose (sampled at reset, fixed during
    an episode) is part of the simulator state. No gravity compensation, as upstream's FR3."""
    parts = fr3_mjcf_parts(ROBOT_PREFIX)
    tag = f'<body name="{ROBOT_PREFIX}fr3_link0"'
    if parts.worldbody.count(tag) != 1:
        raise RuntimeError(f"FR3 MJCF has no body {ROBOT_PREFIX}fr3_link0")
    body = parts.worldbody.replace(tag, f'{tag} mocap="true"')
    return body, parts.actuator, parts.equality, parts.default


def _region_frame(task: TaskSpec, name: str, fixtures: dict[str, FixtureAsset],
                  objects: dict[str, ObjectAsset]) -> RegionFrame:  # fmt: skip
    spec = task.regions[name]
    where = f"{task.file}: regions.{name}"
    if spec.target == GROUND:
        return RegionFrame("ground", GROUND, np.eye(4), spec.align)
    if spec.target in fixtures:
        asset = fixtures[spec.target]
        frame = spec.frame or asset.default_frame
        if frame not in asset.frames:
            raise TaskFileError(
                f"{where}.frame: fixture {spec.target!r} has no frame {frame!r}; frames: "
                f"{sorted(asset.frames)}"
            )
        drawer = asset.drawer_of.get(frame)
        return RegionFrame("fixture", spec.target, asset.frames[frame], spec.align, drawer)
    asset_o = objects[spec.target]
    if spec.frame is None:
        return RegionFrame("object", spec.target, np.eye(4), spec.align)
    if spec.frame not in asset_o.frames:
        raise TaskFileError(
            f"{where}.frame: object {spec.target!r} has no frame {spec.frame!r}; frames: "
            f"{sorted(asset_o.frames)}"
        )
    return RegionFrame("object", spec.target, np.eye(4), spec.align,
                       hinge=asset_o.frames[spec.frame])  # fmt: skip


def _marker(name: str, box: Array, rgba: tuple[float, ...], local: Array) -> str:
    lo, hi = box[:3], box[3:]
    centre = local[:3, :3] @ ((lo + hi) / 2.0) + local[:3, 3]
    half = np.maximum((hi - lo) / 2.0, 1e-4)
    return (
        f'<site name="{name}" type="box" size="{_f(half)}" pos="{_f(centre)}" '
        f'rgba="{_f(rgba)}" group="1"/>'
    )


#: MuJoCo's friction cones, by their MJCF names (``Dynamic3DConfig.cone``).
FRICTION_CONES = ("elliptic", "pyramidal")


def build_scene(
    task: TaskSpec,
    image_size: tuple[int, int],
    timestep: float,
    arm_motors: bool = False,
    cone: str = "elliptic",
    impratio: float = 10.0,
) -> Scene:
    """Assemble the MJCF for ``task``.

    ``image_size`` is (width, height) of offscreen frames. ``timestep`` (the physics step, s),
    ``cone`` (``"elliptic"`` or ``"pyramidal"``) and ``impratio`` are the env config's and are
    written into the MJCF's ``<option>``, so a model compiled from ``Scene.xml`` alone steps as
    the env does.
    """
    if cone not in FRICTION_CONES:
        raise ValueError(f"build_scene: cone must be one of {FRICTION_CONES}, got {cone!r}")
    fixtures = {n: build_fixture(e.kind, n, e.params) for n, e in task.fixtures.items()}
    objects = {n: build_object(e.kind, n, e.params) for n, e in task.objects.items()}
    regions = {n: _region_frame(task, n, fixtures, objects) for n in task.regions}

    # Region markers (only regions with a visible rgba), attached to the body that carries them.
    markers: dict[str, list[str]] = {}
    for n, spec in task.regions.items():
        if spec.rgba is None or spec.rgba[3] <= 0.0:
            continue
        rf = regions[n]
        if rf.hinge is not None:
            body = f"{rf.target}_beam"
            local = pose_matrix(rf.hinge.offset, np.eye(3))
        elif rf.drawer is not None:
            body = rf.drawer
            drawer = next(d for d in fixtures[rf.target].drawers if d.name == rf.drawer)
            local = drawer.frame.copy()
            local[:3, 3] = (0.0, 0.0, 0.01)
        else:
            body = "world" if rf.kind == "ground" else rf.target
            local = rf.local
        for j, box in enumerate(spec.boxes):
            markers.setdefault(body, []).append(_marker(f"region_{n}_{j}", box, spec.rgba, local))

    def with_markers(xml: str, body: str) -> str:
        extra = markers.get(body)
        if not extra:
            return xml
        tag_end = xml.index(">", xml.index(f'name="{body}"')) + 1
        return xml[:tag_end] + "\n" + "\n".join(extra) + xml[tag_end:]

    bodies: list[str] = []
    parked: dict[str, tuple[float, float, float]] = {}
    for j, (n, asset_f) in enumerate(fixtures.items()):
        spec_f = task.fixtures[n]
        if spec_f.pos is not None:
            pos: tuple[float, float, float] = spec_f.pos
            quat = yaw_quat(spec_f.yaw or 0.0)
        else:
            pos = (-60.0 - 8.0 * j, -60.0, 0.0)
            quat = yaw_quat(0.0)
        parked[n] = pos
        xml = asset_f.body(n, pos, quat)
        for drawer in asset_f.drawers:
            xml = with_markers(xml, drawer.name)
        bodies.append(with_markers(xml, n))
    for j, (n, asset_o) in enumerate(objects.items()):
        pos = (60.0 + 3.0 * (j % 30), 60.0 + 3.0 * (j // 30), 5.0)
        parked[n] = pos
        xml = asset_o.body(n, pos, (1.0, 0.0, 0.0, 0.0))
        if asset_o.hinge is not None:
            xml = with_markers(xml, f"{n}_beam")
        bodies.append(with_markers(xml, n))
    statics = [
        f'<geom name="static_{s.name}" type="box" size="{_f(np.array(s.size) / 2)}" '
        f'pos="{_f(s.pos)}" quat="{_f(yaw_quat(s.yaw))}" rgba="{_f(s.rgba)}" '
        f'class="{FIXTURE_CLASS}"/>'
        for s in task.static
    ]
    cameras = []
    for cam in task.cameras.values():
        xy = look_at_xyaxes(list(cam.pos), list(cam.lookat))
        cameras.append(
            f'<camera name="{cam.name}" pos="{_f(cam.pos)}" xyaxes="{_f(xy)}" fovy="{cam.fovy:g}"/>'
        )
    if task.robot == "fr3":
        robot_body, robot_act, robot_eq, robot_default = _fr3_robot_xml()
    else:
        robot_body, robot_act, robot_eq, robot_default = _robot_xml(arm_motors)
    world_markers = "\n".join(markers.get("world", []))
    # A working drawer is a child body of its fixture, a mocap body. MuJoCo 4.0 gives a mocap
    # body a weld id of its own, so its parent filter keeps the drawer from colliding with the
    # fixture; MuJoCo 3.3 welds mocap bodies to the world, where that filter does not apply, and
    # the drawer's back wall (1 cm into the fixture's back panel) would push the drawer 1 cm open.
    # Excluding the pair keeps both versions alike (the drawer slides on its joint and limits).
    excludes = [
        f'    <exclude body1="{n}" body2="{d.name}"/>'
        for n, a in fixtures.items()
        for d in a.drawers
    ]
    contact = f"  <contact>\n{chr(10).join(excludes)}\n  </contact>\n" if excludes else ""
    width, height = image_size
    xml = f"""<mujoco model="kinder_{task.family}">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{float(timestep)!r}" integrator="implicitfast" cone="{cone}"
          impratio="{float(impratio)!r}">
    <flag multiccd="enable"/>
  </option>
  <statistic extent="3" center="1 0 0.5"/>
  <visual>
    <global offwidth="{max(width, 640)}" offheight="{max(height, 480)}"/>
    <map znear="0.005" zfar="30"/>
    <quality shadowsize="2048"/>
    <headlight ambient="0.3 0.3 0.3" diffuse="0.35 0.35 0.35" specular="0.05 0.05 0.05"/>
  </visual>
  <asset>
    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.92 0.94 0.97" rgb2="0.7 0.75 0.82"
      width="64" height="64"/>
    <texture name="floor" type="2d" builtin="checker" rgb1="0.8 0.8 0.78" rgb2="0.74 0.74 0.72"
      width="512" height="512"/>
    <material name="floor" texture="floor" texrepeat="1 1" texuniform="true" specular="0"
      shininess="0"/>
  </asset>
  <default>
{robot_default}
{DEFAULT_CLASSES}
  </default>
  <worldbody>
    <light name="sun" pos="1 -1 4" dir="-0.3 0.3 -1" directional="true" diffuse="0.45 0.45 0.45"
      specular="0.1 0.1 0.1" castshadow="false"/>
    <geom name="floor" type="plane" size="0 0 0.05" material="floor" class="{FIXTURE_CLASS}"/>
{world_markers}
{chr(10).join(statics)}
{chr(10).join(bodies)}
{chr(10).join(cameras)}
{robot_body}
  </worldbody>
{contact}  <equality>
{robot_eq}
  </equality>
  <actuator>
{robot_act}
  </actuator>
</mujoco>
"""
    drawers = {d.name: (fname, d.joint) for fname, fa in fixtures.items() for d in fa.drawers}
    seesaws = {n: a.hinge for n, a in objects.items() if a.hinge is not None}
    robot_cameras = [] if task.robot == "fr3" else [f"{ROBOT_PREFIX}base", f"{ROBOT_PREFIX}wrist"]
    camera_names = [*task.cameras, *robot_cameras]
    return Scene(xml, objects, fixtures, drawers, seesaws, regions, camera_names, parked)
