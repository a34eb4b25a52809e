"""Dynamic3D mechanics: goal predicates on hand-built states, exact set_state replay, the drawer,
the seesaw, random rollouts of every family, and a scripted pick-and-place onto the Shelf3D
shelf (the task is solvable with this gripper and these frictions)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from kinder_core import ObjectCentricState
from kinder_garden3d.dynamic3d.env import Dynamic3DEnv
from kinder_garden3d.robot.description import matrix_to_quat_xyzw
from kinder_garden3d.robot.ik import InverseKinematics

SHELF2_Z = 0.0127 + 2 * (0.254 + 0.0127)  # top of board 2 of the Shelf3D cupboard


@pytest.fixture(scope="module")
def shelf() -> Dynamic3DEnv:
    env = Dynamic3DEnv("Shelf3D/Shelf3D.json", num_objects=2)
    env.reset(seed=0)
    yield env
    env.close()


def _place(state: ObjectCentricState, env: Dynamic3DEnv, name: str, xyz: tuple[float, ...]):
    obj = env.objects[name]
    for f, v in zip(("x", "y", "z"), xyz, strict=True):
        state.set(obj, f, v)


@pytest.mark.parametrize(
    ("timestep", "substeps", "cone", "impratio"),
    [(0.0005, 200, "elliptic", 10.0), (0.001, 100, "pyramidal", 1.0)],
)
def test_the_configured_physics_is_the_compiled_models(timestep, substeps, cone, impratio):
    """The config is the one source of the physics step and the contact settings: the scene's
    MJCF is compiled with them (upstream's 0.5 ms, elliptic cones and impratio 10 by default), so
    a model rebuilt from ``env.scene.xml`` steps alike, state for state."""
    env = Dynamic3DEnv("Shelf3D/Shelf3D.json", num_objects=1,
                       config={"timestep": timestep, "substeps": substeps, "cone": cone,
                               "impratio": impratio})  # fmt: skip
    try:
        rebuilt = mujoco.MjModel.from_xml_string(env.scene.xml)
        cones = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC,
                 "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}  # fmt: skip
        for model in (env.model, rebuilt):
            assert model.opt.timestep == timestep
            assert model.opt.cone == cones[cone]
            assert model.opt.impratio == impratio
        env.reset(seed=3)
        data = mujoco.MjData(rebuilt)
        mujoco.mj_setState(rebuilt, data, _full_state(env.model, env.data), _FULL)
        for _ in range(50):
            data.ctrl[:] = env.data.ctrl
            mujoco.mj_step(env.model, env.data)
            mujoco.mj_step(rebuilt, data)
        np.testing.assert_array_equal(_full_state(rebuilt, data), _full_state(env.model, env.data))
    finally:
        env.close()
    default = Dynamic3DEnv("Shelf3D/Shelf3D.json", num_objects=1).model.opt
    assert (default.timestep, default.cone, default.impratio) == (
        0.0005, mujoco.mjtCone.mjCONE_ELLIPTIC, 10.0)  # fmt: skip


_FULL = mujoco.mjtState.mjSTATE_INTEGRATION


def _full_state(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    out = np.empty(mujoco.mj_stateSize(model, _FULL))
    mujoco.mj_getState(model, data, out, _FULL)
    return out


# -- predicates ----------------------------------------------------------------------------------


def test_on_shelf_region(shelf):
    s = shelf.get_state()
    _place(s, shelf, "cube1", (1.5, 0.0, SHELF2_Z + 0.01))
    atoms = shelf.goal_atoms(s)
    assert atoms == {
        "on(cube1, cupboard_1_goal_region)": True,
        "on(cube2, cupboard_1_goal_region)": False,
    }
    assert not shelf.goal_reached(s)
    _place(s, shelf, "cube2", (1.45, 0.25, SHELF2_Z + 0.02))  # local x = world y (yaw 90)
    assert shelf.goal_reached(s)
    for xyz in [
        (1.5, 0.0, SHELF2_Z + 0.05),  # above the 3 cm box
        (1.5, 0.0, SHELF2_Z - 0.27),  # the shelf below
        (1.5 - 0.2, 0.0, SHELF2_Z + 0.01),  # in front of the cupboard (local y = -world x)
        (1.5, 0.31, SHELF2_Z + 0.01),  # beyond the shelf's side
    ]:
        _place(s, shelf, "cube1", xyz)
        assert not shelf.goal_reached(s), xyz


def test_region_follows_the_drawer():
    env = Dynamic3DEnv("SweepIntoDrawer3D/SweepIntoDrawer3D.json", num_objects=1)
    try:
        s, _ = env.reset(seed=0)
        drawer = env.objects["kitchen_island_drawer_s1c1"]
        # Island at (0.5, 0), yaw -90: local +y (the drawer's pull direction) is world +x.
        inside_closed = (0.5 - 0.2, 0.0, 0.19 + 0.03)
        _place(s, env, "cube_0", inside_closed)
        assert env.goal_reached(s)
        s.set(drawer, "pos", 0.5)  # open 50 cm: the region slides out with the drawer
        assert not env.goal_reached(s)
        _place(s, env, "cube_0", (inside_closed[0] + 0.5, 0.0, inside_closed[2]))
        assert env.goal_reached(s)
    finally:
        env.close()


def test_balanced_and_the_beam_region():
    env = Dynamic3DEnv("BalanceBeam3D/BalanceBeam3D.json")
    try:
        s, _ = env.reset(seed=0)
        seesaw = env.objects["seesaw_1"]
        beam = env.regions.transform(s, "beam_goal_region")
        blocks = {"large_block": 0.15, "small_block_1": -0.05, "small_block_2": -0.12}
        for name, along in blocks.items():
            _place(s, env, name, tuple(beam[:3, :3] @ np.array([along, 0.0, 0.015]) + beam[:3, 3]))
        s.set(seesaw, "hinge_pos", math.radians(3.0))
        assert env.goal_atoms(s) == {**{f"on({n}, beam_goal_region)": True for n in blocks},
                                     "balanced(seesaw_1, 5)": True}  # fmt: skip
        assert env.goal_reached(s)
        s.set(seesaw, "hinge_pos", math.radians(-6.0))
        atoms = env.goal_atoms(s)
        assert not atoms["balanced(seesaw_1, 5)"]
        # The tilted beam moved away from the (unmoved) block: the region rotates with it.
        assert not atoms["on(large_block, beam_goal_region)"]
        assert not env.goal_reached(s)
    finally:
        env.close()


def test_robot_base_region_and_or(tmp_path):
    env = Dynamic3DEnv("Dynamo3D/Dynamo3D.json", num_objects=1)
    try:
        s, info = env.reset(seed=0)
        assert not info["success"]
        robot = env.objects["robot"]
        s.set(robot, "pos_base_x", 1.0)
        s.set(robot, "pos_base_y", 0.1)
        assert env.goal_reached(s)
        s.set(robot, "pos_base_y", 0.3)
        assert not env.goal_reached(s)
    finally:
        env.close()
    task = {
        "family": "Shelf3D",
        "description": "or-goal",
        "objects": {"a": {"type": "cube"}, "b": {"type": "cube"}},
        "regions": {
            "start": {"target": "ground", "boxes": [[2, 2, 0, 3, 3, 0]]},
            "left": {"target": "ground", "boxes": [[0, 1, 0, 1, 2, 1]]},
            "right": {"target": "ground", "boxes": [[0, -2, 0, 1, -1, 1]]},
        },
        "cameras": {"task_view": {"pos": [0, 0, 3], "lookat": [0.5, 0, 0]}},
        "initial_state": [["on", "a", "start"], ["on", "b", "start"]],
        "goal": ["or", ["on", "a", "left"], ["and", ["on", "b", "right"], ["on", "a", "right"]]],
    }
    path = tmp_path / "or.json"
    path.write_text(__import__("json").dumps(task))
    env = Dynamic3DEnv(str(path))
    try:
        s, _ = env.reset(seed=0)
        assert not env.goal_reached(s)
        _place(s, env, "a", (0.5, 1.5, 0.01))
        assert env.goal_reached(s)
        _place(s, env, "a", (0.5, -1.5, 0.01))
        assert not env.goal_reached(s)
        _place(s, env, "b", (0.5, -1.5, 0.01))
        assert env.goal_reached(s)
    finally:
        env.close()


# -- exact replay --------------------------------------------------------------------------------


def test_set_state_replays_a_step_exactly(shelf):
    shelf.reset(seed=3)
    rng = np.random.default_rng(0)
    space = shelf.action_space
    actions = [rng.uniform(space.low, space.high) for _ in range(8)]
    for a in actions[:4]:
        shelf.step(a)
    start = shelf.get_state()
    assert start.sim_state is not None
    first = [shelf.step(a)[0] for a in actions[4:]]
    other = Dynamic3DEnv("Shelf3D/Shelf3D.json", num_objects=2)
    try:
        other.reset(seed=11)
        for env in (shelf, other):
            env.set_state(start)
            for a, expected in zip(actions[4:], first, strict=True):
                got = env.step(a)[0]
                assert np.array_equal(got.data, expected.data)
                assert np.array_equal(got.sim_state, expected.sim_state)
    finally:
        other.close()


def test_features_win_over_a_stale_sim_state(shelf):
    """Editing features of a state (keeping its sim_state) moves the object in the simulator."""
    s, _ = shelf.reset(seed=0)
    edited = s.copy()
    _place(edited, shelf, "cube1", (0.0, -0.6, 0.3))
    zero = np.zeros(11)
    nxt = shelf.transition(edited, zero)[0]
    cube = shelf.objects["cube1"]
    assert abs(nxt.get(cube, "x")) < 1e-3 and abs(nxt.get(cube, "y") + 0.6) < 1e-3
    assert nxt.get(cube, "z") < 0.3  # it fell


def test_box_vector_states_are_deterministic(shelf):
    s, _ = shelf.reset(seed=5)
    vec = shelf.box_space.vectorize(s)
    a = np.full(11, 0.05)
    r1 = shelf.transition(vec, a)[0]
    shelf.step(np.zeros(11))  # disturb the simulator in between
    r2 = shelf.transition(vec, a)[0]
    assert np.array_equal(r1.data, r2.data)
    full = shelf.transition(s, a)[0]  # with the warm start: nearly the same physics
    assert np.allclose(r1.data, full.data, atol=5e-3)


# -- assets --------------------------------------------------------------------------------------


def test_drawer_opens_when_pulled_and_stays_shut_otherwise():
    env = Dynamic3DEnv("SweepIntoDrawer3D/SweepIntoDrawer3D.json", num_objects=1)
    try:
        s, _ = env.reset(seed=0)
        drawer = env.objects["kitchen_island_drawer_s1c1"]
        assert s.get(drawer, "pos") == pytest.approx(0.0, abs=1e-4)
        m, d = env.model, env.data
        body = m.body("kitchen_island_drawer_s1c1").id
        for pull, expect_open in ((0.0, False), (30.0, True)):
            env._load(s)
            d.xfrc_applied[body, :3] = (pull, 0.0, 0.0)  # world +x = the island's front
            mujoco.mj_step(m, d, round(1.0 / m.opt.timestep))  # 1 s
            d.xfrc_applied[body] = 0.0
            env._cache = None  # MjData was stepped behind the env's back
            slide = d.qpos[m.jnt_qposadr[m.joint("kitchen_island_drawer_s1c1_slide").id]]
            if expect_open:
                assert slide > 0.3, slide
            else:
                assert abs(slide) < 1e-3, slide
        # An open drawer (set through its feature) stays open and carries its contents' region.
        opened = s.copy()
        opened.set(drawer, "pos", 0.4)
        opened.set(env.objects["robot"], "pos_base_x", 1.9)  # out of the drawer's way
        after = env.transition(opened, np.zeros(11))[0]
        assert after.get(drawer, "pos") == pytest.approx(0.4, abs=5e-3)
    finally:
        env.close()


def test_seesaw_tips_under_an_off_centre_load_and_not_under_a_centred_one():
    env = Dynamic3DEnv("BalanceBeam3D/BalanceBeam3D.json")
    try:
        s, _ = env.reset(seed=0)
        seesaw = env.objects["seesaw_1"]
        assert abs(s.get(seesaw, "hinge_pos")) < math.radians(1.0)
        beam = env.regions.transform(s, "beam_goal_region")
        angles = {}
        for where in (0.0, 0.15):
            t = s.copy()
            pos = beam[:3, :3] @ np.array([where, 0.0, 0.005 + 0.009 + 0.001]) + beam[:3, 3]
            _place(t, env, "large_block", tuple(pos))  # the 100 g block
            for _ in range(15):
                t = env.transition(t, np.zeros(11))[0]
            angles[where] = t.get(seesaw, "hinge_pos")
            assert env.goal_atoms(t)["on(large_block, beam_goal_region)"]
        # Upstream's seesaw has no base plate: its beam tips until an end rests on the floor,
        # about 2.4 degrees (measured 2.3 with this load), and stays level under a centred one.
        assert abs(angles[0.0]) < math.radians(0.5)
        assert abs(angles[0.15]) > math.radians(2.0)
    finally:
        env.close()


# -- random rollouts -----------------------------------------------------------------------------

ROLLOUTS = [
    ("Shelf3D/Shelf3D.json", 2),
    ("ConstrainedCupboard3D/ConstrainedCupboard3D.json", 1),
    ("Rearrange3D/Rearrange3D-o2-put_the_boxed_drink_and_the_can_next_to_the_bowl.json", None),
    ("SortClutteredBlocks3D/SortClutteredBlocks3D-sort_the_cluttered_blocks_into_bins.json", 4),
    ("SweepSimple3D/SweepSimple3D-sweep_the_blocks_to_the_left_side_of_the_kitchen_island.json", 3),
    ("SweepIntoDrawer3D/SweepIntoDrawer3D.json", 2),
    ("ScoopPour3D/ScoopPour3D.json", 4),
    ("BalanceBeam3D/BalanceBeam3D.json", 3),
    ("Tossing3D/Tossing3D.json", 1),
    ("Dynamo3D/Dynamo3D.json", 3),
]


@pytest.mark.parametrize(("task", "count"), ROLLOUTS, ids=[t.split("/")[0] for t, _ in ROLLOUTS])
def test_200_random_steps_stay_finite_and_above_the_floor(task, count):
    env = Dynamic3DEnv(task, num_objects=count)
    try:
        s, _ = env.reset(seed=1)
        env.action_space.seed(1)
        z_idx = [s.layout.index(env.objects[n], "z") for n in env.task.objects]
        # Height of each bounding box's centre above an object's frame (a frame may lie below
        # the box: a bin's bottom face, a chair's mesh frame): the env's own fall-through test.
        centre = np.array(
            [
                env.scene.objects[n].bbox[2] / 2 - env.scene.objects[n].bottom
                for n in env.task.objects
            ]
        )
        for t in range(200):
            s, *_ = env.step(env.action_space.sample())
            assert np.all(np.isfinite(s.data)), f"NaN/inf at step {t}"
            low = (s.data[z_idx] + centre).min()
            assert low > -0.005, f"an object fell through the floor at step {t}"
    finally:
        env.close()


# -- scripted pick and place ---------------------------------------------------------------------


class _Script:
    """Joint-space steps toward IK targets, with the env's own delta actions."""

    def __init__(self, env: Dynamic3DEnv) -> None:
        self.env = env
        self.robot = env.objects["robot"]
        self.ik = InverseKinematics(free_base=False)
        self.site = env.model.site("robot_pinch_site").id

    def arm(self, s: ObjectCentricState) -> np.ndarray:
        return np.array([s.get(self.robot, f"pos_arm_joint{i}") for i in range(1, 8)])

    def base(self, s: ObjectCentricState) -> np.ndarray:
        return np.array(
            [s.get(self.robot, f) for f in ("pos_base_x", "pos_base_y", "pos_base_rot")]
        )

    def pinch(self, s: ObjectCentricState) -> np.ndarray:
        self.env._load(s)
        mujoco.mj_kinematics(self.env.model, self.env.data)
        return self.env.data.site_xpos[self.site].copy()

    @staticmethod
    def quat(pitch: float) -> np.ndarray:
        """Gripper pointing forward (+x) and pitched down; fingers close along world y."""
        z = np.array([math.cos(pitch), 0.0, -math.sin(pitch)])
        y = np.array([0.0, 1.0, 0.0])
        return matrix_to_quat_xyzw(np.stack([np.cross(y, z), y, z], axis=1))

    def step(self, s, arm=None, base=None, grip=0.0):
        a = np.zeros(11)
        a[10] = grip
        if base is not None:
            a[0:3] = np.clip(np.asarray(base) - self.base(s), -0.1, 0.1)
        if arm is not None:
            a[3:10] = np.clip(arm - self.arm(s), -0.1, 0.1)
        return self.env.step(a)[0]

    def reach(self, s, q, grip, tol, base=None, max_steps=200):
        for _ in range(max_steps):
            s = self.step(s, q, base, grip)
            base_ok = base is None or np.abs(self.base(s) - base).max() < 0.003
            if np.abs(self.arm(s) - q).max() < tol and base_ok:
                return s
        raise AssertionError(f"did not reach {q} (at {self.arm(s)})")

    def line(self, s, q, target, pitch, grip, n=None):
        """A straight pinch-point line, one IK solve per waypoint (seeded, nearest branch)."""
        start = self.pinch(s)
        n = n or max(1, math.ceil(np.linalg.norm(np.asarray(target) - start) / 0.03))
        for k in range(1, n + 1):
            p = start + (np.asarray(target) - start) * k / n
            best = None
            for dp in (0, -5, 5, -10, 10, -15, 15):
                cand = pitch + math.radians(dp)
                r = self.ik.solve(p, self.quat(cand), base_pose=tuple(self.base(s)),
                                  initial_arm_joints=q, restarts=0, position_tolerance=1e-3,
                                  orientation_tolerance=1e-2)  # fmt: skip
                if r.success and (best is None or np.abs(r.arm_joints - q).max() < best[0]):
                    best = (np.abs(r.arm_joints - q).max(), r.arm_joints, cand)
            assert best is not None, f"no IK solution at {p}"
            q, pitch = best[1], best[2]
            s = self.reach(s, q, grip, 0.03 if k < n else 0.005)
        return s, q, pitch


def test_scripted_pick_and_place_onto_the_shelf():
    env = Dynamic3DEnv("Shelf3D/Shelf3D.json", num_objects=1)
    try:
        s, _ = env.reset(seed=0)
        sc = _Script(env)
        cube = env.objects["cube1"]
        cx, cy = s.get(cube, "x"), s.get(cube, "y")
        # Start the base 55 cm behind the cube, facing +x (a state built from features).
        s = s.copy()
        for f, v in (("pos_base_x", cx - 0.55), ("pos_base_y", cy), ("pos_base_rot", 0.0)):
            s.set(sc.robot, f, v)
        env.set_state(s)
        s = env.get_state()
        pitch = math.radians(45)
        home = np.array([0.0, 0.26, math.pi, -2.27, 0.0, 0.96, math.pi / 2])
        r = sc.ik.solve([cx - 0.01, cy, 0.15], sc.quat(pitch), base_pose=tuple(sc.base(s)),
                        initial_arm_joints=home, restarts=0, position_tolerance=1e-3,
                        orientation_tolerance=1e-2)  # fmt: skip
        assert r.success
        s = sc.reach(s, r.arm_joints, 0.0, 0.005)
        s, q, pitch = sc.line(s, r.arm_joints, [cx - 0.005, cy, 0.03], pitch, 0.0)
        for _ in range(8):
            s = sc.step(s, q, None, 1.0)
        assert 0.6 < s.get(sc.robot, "pos_gripper") < 0.95  # closed on the 2 cm cube
        s, q, pitch = sc.line(s, q, [cx - 0.005, cy, SHELF2_Z + 0.045], pitch, 1.0, n=14)
        assert s.get(cube, "z") > SHELF2_Z  # lifted to the height of shelf 2
        # Drive the base so the gripper enters the shelf (cupboard front at x = 1.373).
        reach_x = sc.pinch(s)[0] - sc.base(s)[0]
        for bx in (1.16 - reach_x, 1.46 - reach_x):
            s = sc.reach(s, q, 1.0, 0.005, base=np.array([bx, 0.0, 0.0]), max_steps=300)
        for _ in range(8):
            s = sc.step(s, q, None, 0.0)  # release
        s = sc.reach(s, q, 0.0, 0.005, base=np.array([1.16 - reach_x, 0.0, 0.0]), max_steps=300)
        for _ in range(5):
            s = sc.step(s, q, None, 0.0)
        assert env.goal_reached(s), s[cube][:3]
    finally:
        env.close()


@pytest.mark.parametrize(("cone", "impratio", "slips"), [("elliptic", 10.0, False),
                                                         ("pyramidal", 1.0, True)])  # fmt: skip
def test_a_held_cube_stays_in_the_pads_with_the_default_contacts(cone, impratio, slips):
    """The default contact settings (elliptic cones, impratio 10, as upstream's robot models)
    hold a lifted 2 cm cube still in the pads; MuJoCo's defaults let it creep (~1 mm/s)."""
    env = Dynamic3DEnv("Shelf3D/Shelf3D.json", num_objects=1,
                       config={"cone": cone, "impratio": impratio})  # fmt: skip
    try:
        s, _ = env.reset(seed=0)
        sc = _Script(env)
        cube = env.objects["cube1"]
        cx, cy = s.get(cube, "x"), s.get(cube, "y")
        s = s.copy()
        for f, v in (("pos_base_x", cx - 0.55), ("pos_base_y", cy), ("pos_base_rot", 0.0)):
            s.set(sc.robot, f, v)
        env.set_state(s)
        s = env.get_state()
        pitch = math.radians(45)
        home = np.array([0.0, 0.26, math.pi, -2.27, 0.0, 0.96, math.pi / 2])
        r = sc.ik.solve([cx - 0.01, cy, 0.15], sc.quat(pitch), base_pose=tuple(sc.base(s)),
                        initial_arm_joints=home, restarts=0, position_tolerance=1e-3,
                        orientation_tolerance=1e-2)  # fmt: skip
        assert r.success
        s = sc.reach(s, r.arm_joints, 0.0, 0.005)
        s, q, pitch = sc.line(s, r.arm_joints, [cx - 0.005, cy, 0.03], pitch, 0.0)
        for _ in range(8):
            s = sc.step(s, q, None, 1.0)
        s, q, pitch = sc.line(s, q, [cx - 0.005, cy, 0.2], pitch, 1.0, n=8)
        hold = np.zeros(11)
        hold[10] = 1.0
        for _ in range(10):  # let the lift come to rest
            s = env.transition(s, hold)[0]
        start = np.asarray(s[cube][:3]) - sc.pinch(s)
        for _ in range(30):  # 3 s
            s = env.transition(s, hold)[0]
        drift = float(np.linalg.norm(np.asarray(s[cube][:3]) - sc.pinch(s) - start))
        assert s.get(cube, "z") > 0.1  # still held
        assert (drift > 1.5e-3) == slips, drift
    finally:
        env.close()
