"""The KinematicShelf3D planning model: pick every block off the floor onto the shelf's top board.

Upstream has no planning model for this family. Concepts (over the blocks):

* ``HandEmpty(robot)`` / ``Holding(robot, block)``.
* ``OnFloor(block)``: not held, centre below the env's on-shelf height.
* ``OnShelf(block)``: not held, centre at or above it (the env's goal test for one block).

Operators: ``Pick(?robot, ?block)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty,
OnFloor) and ``Place(?robot, ?block)`` (pre Holding; add HandEmpty, OnShelf; delete Holding).
Goal: every block ``OnShelf`` and ``HandEmpty`` (a release opens the gripper, which the env's
goal asks for).

Skills (motions collision-checked with the env's own pybullet geometry; OMPL for the base and the
arm; IK with the robot model's solver):

* Pick (:class:`ShelfPickController`, a
  :class:`~kinder_gym.models.kinematic3d.pick_release.BlockPickController`): Transport3D's
  pick, with the fingers closing across the block's narrow side (a block is 10 cm long, wider
  than the open gripper).
* Place (:class:`ShelfPlaceController`, a
  :class:`~kinder_gym.models.kinematic3d.pick_release.ReleaseController`): retract the arm
  (carrying the block), drive to a sampled standoff in front of (or behind) the shelf, reach
  above a free slot of the top board, descend until the block is 3 mm above it, open, lift.
  The top board is the one a top-down grasp can reach: the boards below it are only 0.254 m
  apart, less than the wrist needs.

Both drive over the blocks on the floor (:class:`FloorDriveController`), as the env lets the
base do. On five blocks (a development episode, uniform place spots, the base blocked by the
floor's blocks) 40 of 65 skill samples failed: 17 places whose spot collided with a block
placed before, 15 samples with no base path, 5 motions the env stopped, 2 with no arm path, 1
pick approach; the backtracking used up the 60 s budget on 3 of 3 episodes. (On ten blocks
the motions the env stopped were arm paths that turned a continuous joint by more than half a
turn, or went past a joint limit; see :func:`~kinder_gym.models.kinematic3d.tidybot.arm_path`.)

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.kinematic_shelf3d import KinematicShelf3DConfig
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE
from kinder_gym.model import PlanningModel
from kinder_gym.models.kinematic3d.pick_release import (
    BlockPickController,
    ReleaseController,
    board_spot,
    centre_at_least,
    floor_pick_model,
)
from kinder_gym.models.kinematic3d.tidybot import (
    ConfigChecker,
    ConfigWaypoint,
    ReachController,
    bounds_around,
    release_pose,
    top_down_quat,
    yaw_of,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import SkillFailure

#: Height (m) below which an object's top lies under the base chassis's top (0.396 m); the
#: arm cannot reach there within the chassis's footprint.
LOW_OBJECT_TOP = 0.3
#: How often the place's sampler stands in front of the shelf (else behind it).
FRONT_PROB = 0.85
#: Least gap (m) between neighbouring slots' blocks along the board's width (end to end).
SLOT_GAP = 0.01
#: Least gap (m) between neighbouring slots' blocks along the board's depth, where the
#: fingers close (side to side).
FINGER_CLEARANCE = 0.04


class FloorDriveController(ReachController):
    """Lets the base pass over the blocks lying on the floor when the env does not check the
    base for collisions (upstream's rule, the env's default): a low block within the chassis's
    footprint can only touch the chassis, and the env lets it (see
    :attr:`~kinder_gym.models.kinematic3d.tidybot.ConfigChecker.under_base`). Counting those
    contacts as collisions blocked a part of the floor growing with the number of blocks
    (92 of 961 base positions on a grid over the blocks' region, five blocks), which made base
    paths and standoffs fail."""

    def make_checker(self, state: ObjectCentricState) -> ConfigChecker:
        checker = super().make_checker(state)
        if not self.context.config.check_base_collisions:
            checker.under_base = frozenset(
                o.name
                for o in state
                if o.type == CUBOID_TYPE
                and o.name not in checker.moving
                and float(state[o][2]) + float(np.max(state[o][9:12])) < LOW_OBJECT_TOP
            )
        return checker


class ShelfPickController(FloorDriveController, BlockPickController):
    """:class:`~kinder_gym.models.kinematic3d.pick_release.BlockPickController` driving over
    the floor's blocks (:class:`FloorDriveController`). Objects: ``(robot, block)``."""


class ShelfPlaceController(FloorDriveController, ReleaseController):
    """Place the held block on the shelf's top board. Objects: ``(robot, block)``; the shelf is
    the env's.

    The sampler puts the block in a free slot of a grid on the top board (a placed block lies
    along the board's width, the fingers on its sides along the depth: blocks end to end
    ``SLOT_GAP`` apart along the width, side by side ``FINGER_CLEARANCE`` apart along the
    depth; 5 × 2 slots for the env's blocks), preferring the row farther from the chosen side
    whose nearer neighbour is free, so that no placed block stands in the way of the next.
    Uniform spots collided with the blocks placed before ever more often (see the module
    docstring). The base stands off the shelf's edge (not the spot): nearer than 0.28 m the
    retracted arm's block meets the shelf."""

    params_space = spaces.Box(0.0, 1.0, (4,), dtype=np.float64)
    params_doc = (
        "(u, v, dist, side): the block's centre goes to fractions (u, v) of the top board "
        "(shrunk by the block's footprint radius and 2 cm), 3 mm above it; the base stands "
        "0.29 + 0.08·dist metres from the shelf's front edge (side < 1/2) or its back edge, "
        "facing the spot. Sampled: (u, v) a free slot of the board's grid, dist uniform, side "
        "in front with probability FRONT_PROB."
    )

    def planning_bounds(self, state: ObjectCentricState) -> tuple[float, float, float, float]:
        """The robot, the blocks and the shelf, grown by ``PLANNING_MARGIN``."""
        sx, sy, _ = self.env_config(KinematicShelf3DConfig).shelf_pos
        return bounds_around(super().planning_bounds(state), sx, sy)

    def _margin(self, state: ObjectCentricState) -> float:
        o_half = np.asarray(state[self.objects[1]][9:12], dtype=np.float64)
        return float(np.hypot(o_half[0], o_half[1])) + 0.02

    def slots(self, state: ObjectCentricState) -> list[tuple[float, float]]:
        """The grid's slots as (u, v) fractions, by column then row (v ascending)."""
        cfg = self.env_config(KinematicShelf3DConfig)
        long, narrow = self._placed_half(state)
        r = self._margin(state)
        span_x = max(0.0, cfg.shelf.width - 2 * r)
        span_y = max(0.0, cfg.shelf.depth - 2 * r)
        cols = int(span_x // (2 * long + SLOT_GAP)) + 1
        rows = int(span_y // (2 * narrow + FINGER_CLEARANCE)) + 1
        us = [i / (cols - 1) for i in range(cols)] if cols > 1 else [0.5]
        vs = [j / (rows - 1) for j in range(rows)] if rows > 1 else [0.5]
        return [(u, v) for u in us for v in vs]

    def _placed_half(self, state: ObjectCentricState) -> tuple[float, float]:
        """The held block's half extents along x and y once placed (its long side along x)."""
        o_half = state[self.objects[1]][9:12]
        return float(max(o_half[0], o_half[1])), float(min(o_half[0], o_half[1]))

    def occupied(self, state: ObjectCentricState, u: float, v: float) -> bool:
        """Whether a block resting on the top board comes within ``SLOT_GAP`` (along x) or
        ``FINGER_CLEARANCE`` (along y) of the held block placed at fractions (u, v)."""
        _, obj = self.objects
        cfg = self.env_config(KinematicShelf3DConfig)
        top = cfg.shelf.surface_heights(cfg.shelf_pos[2])[-1]
        px, py = board_spot(cfg.shelf, cfg.shelf_pos, u, v, self._margin(state))
        long, narrow = self._placed_half(state)
        hx = long + SLOT_GAP / 2 - 0.001
        hy = narrow + FINGER_CLEARANCE / 2 - 0.001
        for other in state:
            if other.type != CUBOID_TYPE or other == obj or state[other][7] > 0.5:
                continue
            f = state[other]
            if float(f[2]) < top:
                continue
            yaw = yaw_of(np.asarray(f[3:7]))
            c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
            ax, ay = c * f[9] + s * f[10], s * f[9] + c * f[10]
            if abs(f[0] - px) < ax + hx and abs(f[1] - py) < ay + hy:
                return True
        return False

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        dist = float(rng.uniform(0.0, 1.0))
        # Mostly from the front: behind the shelf the base must drive round it (a longer
        # base path and more steps).
        side = float(rng.uniform(0.0, 0.5) if rng.uniform() < FRONT_PROB else rng.uniform(0.5, 1.0))
        free = [uv for uv in self.slots(state) if not self.occupied(state, *uv)]
        if not free:
            return np.array([*rng.uniform(0.0, 1.0, 2), dist, side])
        by_col: dict[float, list[float]] = {}
        for u, v in self.slots(state):
            by_col.setdefault(u, []).append(v)
        best: list[tuple[float, float]] = []
        for u, vs in by_col.items():
            # Near to far (from the front, side < 1/2, the near row has the smaller v): the
            # farthest free slot with only free slots before it.
            choice = None
            for w in sorted(vs, reverse=side >= 0.5):
                if (u, w) not in free:
                    break
                choice = w
            if choice is not None:
                best.append((u, choice))
        pool = best or free
        u, v = pool[int(rng.integers(len(pool)))]
        return np.array([u, v, dist, side])

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, obj = self.objects
        u, v, dist_p, side = (float(p) for p in self.params)
        if self.occupied(state, u, v):
            raise SkillFailure(f"{type(self).__name__}: the spot is taken by a placed block")
        cfg = self.env_config(KinematicShelf3DConfig)
        shelf = cfg.shelf
        top = shelf.surface_heights(cfg.shelf_pos[2])[-1]
        o_half = np.asarray(state[obj][9:12], dtype=np.float64)
        px, py = board_spot(shelf, cfg.shelf_pos, u, v, self._margin(state))
        pz = top + o_half[2] + 0.003
        angle = math.pi / 2 if side < 0.5 else -math.pi / 2
        # Measured from the shelf's edge: nearer than 0.28 m the retracted arm's held block
        # meets the shelf, and the arm reaches the top board's spots up to 0.56 m away.
        edge = (
            cfg.shelf_pos[1] - shelf.depth / 2 if side < 0.5 else cfg.shelf_pos[1] + shelf.depth / 2
        )
        dist = abs(py - edge) + 0.29 + 0.08 * dist_p
        ee_p, ee_q = release_pose(state, robot, np.array([px, py, pz]), top_down_quat(angle))
        base_goal = self._standoff(state, np.array([px, py]), dist, angle)
        return self._place_sequence(state, base_goal, ee_p, ee_q)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The KinematicShelf3D planning model (any number of blocks)."""
    cfg = env.config  # type: ignore[attr-defined]
    on_shelf = centre_at_least(cfg.shelf_pos[2] + cfg.shelf.spacing - cfg.on_shelf_z_tolerance)
    cubes = list(env.cubes)  # type: ignore[attr-defined]
    skills = (ShelfPickController, ShelfPlaceController)
    return floor_pick_model(env, "kinematic_shelf3d", cubes, "?block", "OnShelf", on_shelf, skills)


__all__: Sequence[str] = [
    "FINGER_CLEARANCE",
    "FRONT_PROB",
    "LOW_OBJECT_TOP",
    "SLOT_GAP",
    "FloorDriveController",
    "ShelfPickController",
    "ShelfPlaceController",
    "create_model",
]
