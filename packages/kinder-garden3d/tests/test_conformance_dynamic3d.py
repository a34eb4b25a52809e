"""Dynamic3D conforms to upstream kindergarden 0.2.5, checked against recorded fixtures.

The fixtures (``tests/data/conformance/Shelf3D-o1.json``, ``SweepIntoDrawer3D-o5.json``) were
recorded from upstream with ``tools/conformance/record_upstream.py kinder/Shelf3D-o1-v0
kinder/SweepIntoDrawer3D-o5-v0 --seeds 100 --full 5 --random 3 --steps 30 --no-scripts``.

Reset distributions are compared feature by feature (ranges and a two-sample KS test), with three
rules the physics needs:

* Values are rounded to a resolution per feature kind first (``RESOLUTION``: 1 mm, 1 mrad,
  0.01 for quaternion components and velocities): resting objects sit 0.1 mm deeper in
  upstream's contacts, and features that settle to rest carry MuJoCo's numerical noise on both
  sides (1e-18 … 1e-6). A feature whose rounded values on both sides lie within one resolution
  step of one another matches.
* Upstream stores fixture positions in float32 (2.619999885559082 for 2.62): constants are equal
  to ``CONST_ATOL``.
* The five SweepIntoDrawer3D cubes are exchangeable (the same region, size and drop): their
  features are compared pooled over the cubes, so a rare event (a cube landing on another) is
  compared over 5 × the seeds. Upstream places the wiper on the floor at the origin when 100 draws
  fail (about 1 seed in 40); those seeds are left out (ours keeps drawing; a kept deviation).

Transitions: MuJoCo states cannot be compared to 1e-9 across two different simulators (upstream
cannot even reload its own Dynamic3D state faithfully), so each recorded step is replayed *one step
at a time* from upstream's state before it (every simulator quantity of the robot and the objects is
in the state vector: joint positions and velocities, object poses and velocities), and the errors
after it are compared per feature group with a stated tolerance on their median and maximum over
all steps (``STEP_TOL``; measured on the fixtures, ``one_step_errors``):

* base pose (m, rad): median 1e-3, max 0.15; measured median 1.4e-4, max 2.6e-4 on Shelf3D-o1
  and 0.12 on SweepIntoDrawer3D-o5, where random actions push the robot into the island and
  upstream's mesh robot is stopped earlier than our primitive-shape robot;
* arm joints (rad): median 0.04, max 0.08; measured median 0.029, max 0.051. Upstream computes
  the arm's PD torque (with its bias compensation) once per action and holds it for the 0.1 s of
  the action; ours servo the arm at every physics step;
* gripper closure: median 0.01, max 0.02; measured max 0.01;
* object positions (m): median and max 1e-3; measured 2e-12 on Shelf3D-o1 and 1.0e-4 on
  SweepIntoDrawer3D-o5, where the cubes resting on the island sit 0.13 mm deeper in upstream's
  contacts.

The SweepIntoDrawer3D fixture keeps the first 15 steps of two of the three recorded random
trajectories (the fixture stays under 200 KB).

ConstrainedCupboard3D-o1 (recorded the same way) needs no family rule: its one-step errors are
base median 1.3e-4, max 2.5e-4; arm median 0.029, max 0.051; gripper max 0.010; objects 2e-12.

Dynamo3D-o1 (recorded the same way; ``KEPT``, ``STEP_TOL_BY_ID``): upstream observes its mesh
armchair's site box (0.5 x 0.5 x 0.9 m) as bb_x, bb_y, bb_z, ours its stand-in's collision box
(upstream's stated 0.7 x 0.8 x 0.8 m footprint), and upstream's chair still rocks after the
settle (angular velocity up to 0.03 rad/s), ours rests: those features are left out. When the
robot drives into the chair (5 of the 90 random steps), the mesh chair and our primitive one
move differently: objects max 0.05 m (measured 0.046; median 4.4e-4). Other one-step errors:
base median 1.4e-4, max 2.7e-3; arm median 0.029, max 0.051; gripper max 0.010.
Dynamo3D-o3 (recorded the same way; the fixture keeps the first 20 steps of the three random
trajectories) leaves out the same features of its three chairs (upstream reports 0.5 x 0.5 x 0.9 m
for each mesh chair); one-step errors base median 1.4e-4, max 2.5e-4; arm median 0.028, max
0.043; gripper max 0.011; objects 4.6e-4.

Rearrange3D-o1-put_the_boxed_drink_next_to_the_bowl (recorded the same way): upstream's mesh
drink box, dropped from up to 25 cm onto the island as ours, still rocks after the settle (angular
velocity up to 8.9 rad/s in 21 of 40 seeds, its heading 1 degree either side) and lies tipped
over in 3 of 40, ours stands still: its orientation and velocities are left out (``KEPT``) and its
height compared by the KS test alone. One step of the arm's per-physics-step PD differs from
upstream's held torque by up to 0.22 rad on joint 3 in one random trajectory (9.4e-3 with
``arm_control="held_torque"``): arm max 0.25 there. Other one-step errors: base median 1.5e-4,
max 0.142; objects 4.6e-4.

SortClutteredBlocks3D-o4-sort_the_cluttered_blocks_into_bins (recorded the same way): the four
2 cm blocks dropped into a 7 x 7 cm pile are exchangeable and pooled; which face a tumbling block
lands on is chance, so their orientation and velocities are compared by the KS test alone. Ours
spread a little wider than upstream's (x -0.047..0.058 m over 100 seeds, upstream -0.038..0.035 m
over 40; both at most two high; on MuJoCo 4.0.0 at 1 ms ours stacked three high): their positions
too are compared by the KS test alone (a kept deviation of the primitive contacts). One-step
errors: base median 1.3e-4, max 2.5e-4; arm median 0.028, max 0.044; gripper max 0.009; objects
1.0e-4 (the fixture keeps the first 14 steps of two of the three random trajectories).

SortClutteredBlocks3D-o12-sort_the_blocks_into_the_cupboard (recorded with ``--seeds 40 --full 5
--random 2 --steps 15``; the fixture keeps the 15 steps of the first trajectory): upstream places
the floor objects without a collision check, so a 70 cm rod may come to rest across a 4 cm cube
(5-8 of 40 seeds per rod) and a cube placed into another tumbles onto another face (3 of 360
placements); ours draws again until nothing overlaps (a kept deviation): the objects' height and
tilt are compared by the KS test alone. One-step errors: base median 1.2e-4, max 2.4e-4; arm
median 0.025, max 0.037; gripper max 0.010; objects 4e-8.
SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bins (recorded the same way), checked
under o4's rules: its twenty blocks pooled and compared by the KS test alone, and its bins too
(x, y, yaw, tilt, velocities): a falling block now and then knocks a bin, over 200 seeds by more
than 2 mm in 4 of ours (at most 5.8 mm) and 2 of upstream's (at most 2.9 mm), turning it more
than 5 mrad in 5 of ours and 4 of upstream's, and none of upstream's 40 recorded seeds has one.
SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bowls (slow; recorded the same way; the
fixture keeps 2 full reset vectors, the first 5 steps of the first trajectory, and its
distribution samples rounded to 1e-4, below the comparison's resolution, to stay under 200 KB):
the twenty 2 cm blocks are pooled and compared by the KS test alone (as o4's into bins), but
for their angular velocities, left out (``KEPT``): upstream's pile of twenty is still moving
after the ten settle actions (363 of its 800 blocks turn faster than 5 mrad/s), ours has come
to rest (over 100 seeds the KS test on ``wy`` fails, 0.084 against 0.082).
Upstream's generated bowl collides as the convex hull of its mesh, a solid dome on its pole that
still rocks and spins after the settle (angular velocity up to 6 rad/s, tilt up to 0.19 in qx,
qy); ours is a hollow primitive bowl at rest: the bowls' tilt and velocities are left out
(``KEPT``), their height and yaw (qw, qz: a spinning dome carries its yaw across 0) compared by
the KS test alone. The rocking domes move up to 1.8 mm in one step: objects median and max
3e-3 (``STEP_TOL_BY_ID``; measured median 1.6e-3, max 1.8e-3, all of it the bowls'). Other
one-step errors: base median 1.2e-4, max 2.5e-4; arm median 0.023, max 0.039; gripper max 0.008.

Tossing3D-o1 (recorded the same way) needs no family rule: one-step errors base median 1.3e-4,
max 2.5e-4; arm median 0.029, max 0.051; gripper max 0.010; objects 3e-12.

BalanceBeam3D-o3 (recorded the same way; the fixture keeps the first 20 steps of the three random
trajectories): ours also observes the seesaw's hinge (``EXTRA_FEATURES``, a kept deviation), left
out of the comparison and set to 0 (the beam at rest, level) in states built from upstream's
vectors. The two small blocks are exchangeable and pooled (``small_block_*``); a small block
tumbles onto another face in 2 of upstream's 80 placements (none of ours), so their orientation
is compared by the KS test alone. Upstream's seesaw still rocks after the settle (its angular
velocity up to 0.019 rad/s, its mesh pivot), ours rests: both lie within ``SETTLE_NOISE``.
One-step errors: base median 1.4e-4, max 2.5e-4; arm median 0.028, max 0.042; gripper max 0.010;
objects 1.0e-4 (the blocks resting 0.1 mm deeper in upstream's contacts).

ScoopPour3D-o10 (recorded the same way; the fixture keeps 3 full reset vectors and the first 8
steps of one random trajectory, to stay under 200 KB): the ten 1 cm cubes dropped into the yellow
bin are exchangeable and pooled; which face a tumbling cube lands on, how high it settles (a
cube resting on another) and the velocities it still has are chance, so their orientation, height
and velocities are compared by the KS test alone. Upstream reports the scoop's bounding box from
its size formula (8.9 x 5.4 cm), 4 mm more than its geometry, which ours reports (``KEPT``).
Upstream's contacts sink deeper under load: its yellow bin sits 0.6 mm lower under the cubes and
the cubes 0.9 mm lower, so heights are compared after removing that offset (``HEIGHT_SHIFT``).
One-step errors: base median 1.3e-4, max 2.4e-4; arm median 0.025, max 0.038; gripper max 0.010;
objects 9.1e-4 (the cubes rising out of upstream's deeper contacts in the first step).

SweepSimple3D-o1-sweep_the_blocks_to_the_left_side_of_the_kitchen_island (recorded the same way;
``STEP_TOL_BY_ID``): the upright wiper and the 2 cm cube match upstream's reset distribution
with no family rule (30 and 100 seeds). Random actions drive the robot into the side counter
(base y about 1.95 m), where upstream's mesh robot turns less than our primitive one: base max
0.2 (measured 0.173 in one of the 90 steps; median 1.4e-4). Other one-step errors: arm median
0.028, max 0.047; gripper max 0.011; objects 2e-12.

PickPlace3D-o1 (recorded the same way, 100 seeds) needs no family rule: one-step errors base
median 1.3e-4, max 2.5e-4; arm median 0.029, max 0.051; gripper max 0.010; objects 2e-12.

FrankaPickPlace3D-o1 (recorded the same way, 100 seeds; the FR3 arm): the arm settles under
gravity to the same pose on every seed, stored by upstream as constants; ours settles within
2.1e-5 rad of upstream's elbow (joint 4; the other joints within 1e-6), which is compared to
1e-4 rad (``CONST_TOL``). One-step errors (both arms are joint position servos): mount 0; arm
median 1.6e-3, max 4.7e-3; gripper median 4e-3, max 0.013; objects 1.4e-4 (the cube resting
0.1 mm deeper in upstream's contacts).

Variants (``VARIANT_IDS``, slow): every other Shelf3D, ConstrainedCupboard3D and Rearrange3D id
is recorded too (30 seeds, one random trajectory of 10 steps) and checked under its family's
rules, keyed by family name, beside the id rules above:

* Shelf3D o2-o8: upstream draws each cube's centre height in [0, 0.1] m, starting some cubes
  partly below the floor, and places the robot anywhere in [-1, 1]^2 without keeping it clear of
  the cubes; now and then a cube comes out of the settle turned or knocked (1 cube in 30 seeds on
  o3, 2 on o6; none of ours), so the cubes are compared by the KS test alone. In the random
  trajectories of o2 and o8 upstream's robot starts 0.26 m and 0.11 m from a cube, which our
  primitive base touches and upstream's mesh base does not: objects median 0.02, max 0.06 on o2
  and median 0.03, max 0.07 on o8 (measured on MuJoCo 3.3.7 at 0.5 ms: o8 median 0.015 over
  one step and 0.024 over the first steps, max 0.064; on MuJoCo 4.0.0 at 1 ms o2 median
  0.010, max 0.043 and o8 median 0.016, max 0.059; the other groups as on o1).
* ConstrainedCupboard3D o2-o6: the rods are dropped from up to 10 cm (``drop: centre``, as
  upstream's ground sampler) and, on both sides, now and then one lands across another; which
  one and how it tilts is chance at 30 seeds, so the rods' heights, orientations and velocities
  are compared by the KS test alone.
* Tossing3D-o2 and Dynamo3D-o12: no family rule beyond the first ids'.
* SweepSimple3D o5-o50: the 2 cm cubes dropped from up to 10 cm are exchangeable and pooled;
  which face one lands on (a few in 30 seeds land on an edge against another, on both sides) is
  chance, so their height, orientation and velocities are compared by the KS test alone. The o50
  fixtures keep 20 seeds, one full vector and 3 steps (``tools/conformance/README.md``, "Slim
  fixtures"), to stay under 200 KB.
* ScoopPour3D o20-o50: upstream's contacts sink deeper the heavier the pile, the bin and the
  cubes alike (cubes 1.3 mm below ours under twenty cubes, 2.7 mm under fifty): heights are
  compared after removing up to 3 mm of offset, and one step from upstream's state lifts the
  cubes out of the deeper contacts (objects max 4e-3 m; measured 1.2e-3, 1.7e-3, 2.8e-3 and
  3.3e-3 on o20-o50). Slimmed like the o50 sweeps (o50: 15 seeds, 2 steps).
* ScoopPour3D-o100 (recorded with ``--seeds 12 --full 2 --random 1 --steps 4``, slimmed to 12
  seeds, one vector and one step: ``tools/conformance/README.md``): under a hundred cubes
  upstream's pile sinks 5.1 mm below ours and its yellow bin 4.9 mm (heights compared after
  removing up to 6 mm), and the first step from upstream's state lifts the cubes by 6.3 mm
  (objects max 7e-3). Sunk into itself, upstream's pile has more of its cubes tilted (over
  1 degree: 51 % of its 1,200 cubes against 26 % of our 3,000 on seeds 1000..1029; over 10
  degrees 14 % against 9 %) and still turning (angular speed over 0.05 rad/s: 28 % against 15 %):
  the cubes' qx, qy and angular velocities are left out (``KEPT``); their yaw and positions are
  compared.
* Rearrange3D: the drink's rocking and the can's 0.4 mm box are kept as for the first id; in 1
  of upstream's 30 o2 seeds the can lands against the island's drawer and slides it 8 mm open
  (none of ours), so the drawers are compared by the KS test alone.
"""

from __future__ import annotations

from dataclasses import replace
from fnmatch import fnmatch
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest

import kinder_core
from kinder_core.conformance import (
    Fixture,
    RecordProperty,
    ks_critical,
    ks_statistic,
    load_fixture,
    sample_resets,
)

DATA = Path(__file__).parent / "data" / "conformance"
IDS = (
    "Shelf3D-o1",
    "SweepIntoDrawer3D-o5",
    "ConstrainedCupboard3D-o1",
    "Tossing3D-o1",
    "BalanceBeam3D-o3",
    "ScoopPour3D-o10",
    "Dynamo3D-o1",
    "Dynamo3D-o3",
    "Rearrange3D-o1-put_the_boxed_drink_next_to_the_bowl",
    "SortClutteredBlocks3D-o4-sort_the_cluttered_blocks_into_bins",
    "SortClutteredBlocks3D-o12-sort_the_blocks_into_the_cupboard",
    "SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bowls",
    "SweepSimple3D-o1-sweep_the_blocks_to_the_left_side_of_the_kitchen_island",
    "PickPlace3D-o1",
    "FrankaPickPlace3D-o1",
)
#: The other variants of those families (more objects, another goal), each recorded with
#: ``--seeds 30 --full 3 --random 1 --steps 10 --no-scripts`` and checked under its family's rules
#: (the entries below keyed by family name); slow, so they run in ``make test-all``.
VARIANT_IDS = (
    "Shelf3D-o2",
    "Shelf3D-o3",
    "Shelf3D-o4",
    "Shelf3D-o6",
    "Shelf3D-o8",
    "ConstrainedCupboard3D-o2",
    "ConstrainedCupboard3D-o3",
    "ConstrainedCupboard3D-o4",
    "ConstrainedCupboard3D-o5",
    "ConstrainedCupboard3D-o6",
    "Rearrange3D-o1-put_the_boxed_drink_behind_the_bowl",
    "Rearrange3D-o1-put_the_boxed_drink_in_front_of_the_bowl",
    "Rearrange3D-o1-put_the_boxed_drink_on_the_left_side_of_the_bowl",
    "Rearrange3D-o1-put_the_boxed_drink_on_the_right_side_of_the_bowl",
    "Rearrange3D-o2-put_the_boxed_drink_and_the_can_next_to_the_bowl",
    "Rearrange3D-o2-put_the_boxed_drink_in_front_of_and_the_can_behind_the_bowl",
    "Rearrange3D-o2-put_the_boxed_drink_on_the_left_and_the_can_on_the_right_side_of_the_bowl",
    "Rearrange3D-o2-put_the_can_in_front_of_and_the_boxed_drink_behind_the_bowl",
    "Rearrange3D-o2-put_the_can_on_the_left_and_the_boxed_drink_on_the_right_side_of_the_bowl",
    "Tossing3D-o2",
    "Dynamo3D-o12",
    "SweepSimple3D-o5-sweep_the_blocks_to_the_left_side_of_the_kitchen_island",
    "SweepSimple3D-o10-sweep_the_blocks_to_the_left_side_of_the_kitchen_island",
    "SweepSimple3D-o50-sweep_the_blocks_to_the_left_side_of_the_kitchen_island",
    "SweepSimple3D-o50-sweep_the_blocks_to_the_right_side_of_the_kitchen_counter",
    "SweepSimple3D-o50-sweep_the_blocks_to_the_right_side_of_the_kitchen_island",
    "ScoopPour3D-o20",
    "ScoopPour3D-o30",
    "ScoopPour3D-o40",
    "ScoopPour3D-o50",
    "ScoopPour3D-o100",
    "SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bins",
)
#: Fully recorded ids whose checks are slow (a reset of SortClutteredBlocks3D-o20 settles twenty
#: blocks, ~2 s), so they run in ``make test-all``; their family's smaller ids run by default.
SLOW_IDS = ("SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bowls",)
SETTLE_ATOL = 1e-9  # float rounding after the resolution
CONST_ATOL = 1e-6
#: Upstream constants that are a settled physical result rather than a stored number, with the
#: tolerance they are compared to: the FR3's elbow after the settle (module docstring).
CONST_TOL = {"kinder/FrankaPickPlace3D-o1-v0": {"robot.pos_arm_joint4": 1e-4}}
#: Range slack, as a share of upstream's range at each end: at least 10 %, and for n samples (the
#: smaller side's count) at least the gap a uniform sample of n leaves at an end with probability
#: 1e-4, 1 - 1e-4^(1/n).
RANGE_SLACK = 0.1
RANGE_MISS = 1e-4
ALPHA = 1e-3
#: Features pooled over exchangeable objects: id -> object-name prefix.
POOLED = {
    "ScoopPour3D": "cube_",
    "SweepSimple3D": "cube_",
    "kinder/SortClutteredBlocks3D-o4-sort_the_cluttered_blocks_into_bins-v0": "cube",
    "kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bins-v0": "cube",
    "kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bowls-v0": "cube",
    "kinder/SweepIntoDrawer3D-o5-v0": "cube_",
    "kinder/BalanceBeam3D-o3-v0": "small_block_",
}
#: Pooled features compared by the KS test alone: the orientation and angular velocity of the
#: dropped cubes, whose extremes come from the few cubes that tumble (12 of 200 upstream, 6 of 150
#: ours over 40 and 30 seeds).
POOLED_TAILS = {
    # Keys without "kinder/" are family rules (module docstring, "Variants").
    "Shelf3D": {
        f"cube*.{f}"
        for f in ("x", "y", "z", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "vx", "vy", "vz")
    },
    "ConstrainedCupboard3D": {
        f"cuboid_*.{f}" for f in ("z", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "vx", "vy", "vz")
    },
    "Rearrange3D": {"boxed_drink_0.z", "kitchen_island_drawer_*.pos"},
    "SweepSimple3D": {
        f"cube_*.{f}" for f in ("z", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "vx", "vy", "vz")
    },
    "ScoopPour3D": {
        f"cube_*.{f}" for f in ("z", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "vx", "vy", "vz")
    },
    "kinder/SortClutteredBlocks3D-o4-sort_the_cluttered_blocks_into_bins-v0": {
        f"cube*.{f}"
        for f in ("x", "y", "z", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "vx", "vy", "vz")
    },
    "kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bins-v0": {
        f"{o}*.{f}"
        for o in ("cube", "bin")
        for f in ("x", "y", "z", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "vx", "vy", "vz")
    },
    "kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bowls-v0": {
        *(
            f"cube*.{f}"
            for f in ("x", "y", "z", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "vx", "vy", "vz")
        ),
        *(f"bowl_{c}.{f}" for c in ("red", "green", "blue", "yellow") for f in ("z", "qw", "qz")),
    },
    "kinder/SortClutteredBlocks3D-o12-sort_the_blocks_into_the_cupboard-v0": {
        f"{c}_{o}.{f}"
        for c in ("red", "green", "blue")
        for o in ("cuboid1", "cube1", "cube2", "cube3")
        for f in ("z", "qw", "qx", "qy")
    },
    "kinder/Rearrange3D-o1-put_the_boxed_drink_next_to_the_bowl-v0": {
        f"boxed_drink_0.{f}" for f in ("z",)
    },
    "kinder/SweepIntoDrawer3D-o5-v0": {
        f"cube_*.{f}" for f in ("qw", "qx", "qy", "qz", "wx", "wy", "wz", "vx", "vy", "vz")
    },
    "kinder/BalanceBeam3D-o3-v0": {f"small_block_*.{f}" for f in ("qw", "qx", "qy", "qz")},
}
#: Features that settle to rest in ours but keep a small motion in upstream's, with the bound
#: (absolute) within which both sides match: upstream's seesaw pivot (a convex mesh) still
#: rocks at up to 0.019 rad/s after the ten settle steps (21 of 40 seeds above 0.005).
SETTLE_NOISE = {"kinder/BalanceBeam3D-o3-v0": {f"seesaw_1.{f}": 0.03 for f in ("wx", "wy", "wz")}}
#: Our features that upstream does not observe (left out of every comparison, set to 0 when a
#: state is built from upstream's vector): BalanceBeam3D's seesaw hinge (env docstring).
EXTRA_FEATURES = {"kinder/BalanceBeam3D-o3-v0": ("seesaw_1.hinge_pos", "seesaw_1.hinge_vel")}
#: Per-step tolerances of the one-step replay, by feature group: (median, max) over every step
#: (see the module docstring).
STEP_TOL = {
    "base": (1e-3, 0.15),
    "arm": (0.04, 0.08),
    "gripper": (0.01, 0.02),
    "objects": (1e-3, 1e-3),
}
#: Resolution of the distribution comparison by feature kind: values are rounded to it on both
#: sides first, so that resting contact depths (0.1 mm) and settling noise do not count.
RESOLUTION = {"position": 1e-3, "angle": 1e-3, "quaternion": 1e-2, "velocity": 1e-2}
#: Features left out of the distribution comparison, kept deviations (module docstring).
KEPT = {
    "Rearrange3D": {
        *(
            f"boxed_drink_0.{f}"
            for f in ("qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
        ),
        "can_0.bb_x",
        "can_0.bb_y",
    },
    "ScoopPour3D": {"scoop_0.bb_x", "scoop_0.bb_y"},
    "kinder/ScoopPour3D-o100-v0": {
        "scoop_0.bb_x",
        "scoop_0.bb_y",
        *(f"cube_*.{f}" for f in ("qx", "qy", "wx", "wy", "wz")),
    },
    "Dynamo3D": {f"obstacle_chair*.{f}" for f in ("bb_x", "bb_y", "bb_z", "wx", "wy", "wz")},
    "kinder/Rearrange3D-o1-put_the_boxed_drink_next_to_the_bowl-v0": {
        f"boxed_drink_0.{f}" for f in ("qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
    },
    "kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bowls-v0": {
        *(
            f"bowl_{c}.{f}"
            for c in ("red", "green", "blue", "yellow")
            for f in ("qx", "qy", "vx", "vy", "vz", "wx", "wy", "wz")
        ),
        *(f"cube{i}.{f}" for i in range(1, 21) for f in ("wx", "wy", "wz")),
    },
}
#: Heights compared after removing the offset between the two sides' medians, up to this much
#: (m): upstream's contacts sink deeper under load (ScoopPour3D: the yellow bin under ten 0.1 kg
#: cubes 0.6 mm, the cubes on its floor 0.9 mm; measured on seeds 1000..1029 against upstream's;
#: under fifty cubes 2.5 and 2.7 mm, on seeds 1000..1019).
HEIGHT_SHIFT = {
    "kinder/ScoopPour3D-o10-v0": 1.5e-3,
    "ScoopPour3D": 3e-3,
    "kinder/ScoopPour3D-o100-v0": 6e-3,
}
#: Per-id one-step tolerances that replace ``STEP_TOL``'s for some groups (module docstring).
STEP_TOL_BY_ID = {
    "kinder/Shelf3D-o2-v0": {"objects": (0.02, 0.06)},
    "kinder/Shelf3D-o8-v0": {"objects": (0.03, 0.07)},
    "kinder/Rearrange3D-o1-put_the_boxed_drink_next_to_the_bowl-v0": {"arm": (0.04, 0.25)},
    "kinder/Dynamo3D-o1-v0": {"objects": (1e-3, 0.05)},
    "kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bowls-v0": {
        "objects": (3e-3, 3e-3)
    },
    "SweepSimple3D": {"base": (1e-3, 0.2)},
    "kinder/ScoopPour3D-o10-v0": {},
    "ScoopPour3D": {"objects": (4e-3, 4e-3)},
    "kinder/ScoopPour3D-o100-v0": {"objects": (7e-3, 7e-3)},
}


@pytest.fixture(
    scope="module",
    params=[
        *(pytest.param(i, marks=pytest.mark.slow) if i in SLOW_IDS else i for i in IDS),
        *(pytest.param(v, marks=pytest.mark.slow) for v in VARIANT_IDS),
    ],
)
def fixture(request: pytest.FixtureRequest) -> Fixture:
    return load_fixture(DATA / f"{request.param}.json")


def _rule(table: dict[str, Any], env_id: str, default: Any) -> Any:
    """``table``'s entry for the id, else for its family (a key without ``kinder/``)."""
    if env_id in table:
        return table[env_id]
    return table.get(env_id.split("/", 1)[1].split("-", 1)[0], default)


def _listed(name: str, patterns: Any) -> bool:
    """Whether a feature (or pooled feature) name matches one of ``patterns`` (fnmatch)."""
    return any(name == p or fnmatch(name, p) for p in patterns)


def _upstream_rows(fx: Fixture) -> dict[str, np.ndarray]:
    """Upstream's sampled features (seeds where upstream fell back to its floor placement
    dropped)."""
    samples = {k: np.asarray(v, dtype=np.float64) for k, v in fx.resets.samples.items()}
    if fx.env_id == "kinder/SweepIntoDrawer3D-o5-v0":
        keep = samples["wiper_0.z"] > 0.1
        samples = {k: v[keep] for k, v in samples.items()}
    return samples


def _group(name: str, env_id: str) -> str:
    prefix: str | None = _rule(POOLED, env_id, None)
    if prefix and name.startswith(prefix):
        return f"{prefix}*.{name.split('.', 1)[1]}"
    return name


def _resolution(name: str) -> float:
    feature = name.rsplit(".", 1)[1]
    if feature in ("qw", "qx", "qy", "qz"):
        return RESOLUTION["quaternion"]
    if feature.startswith(("v", "w")) or feature.startswith("vel_"):
        return RESOLUTION["velocity"]
    if feature.startswith("pos_arm") or feature == "pos_base_rot":
        return RESOLUTION["angle"]
    return RESOLUTION["position"]


def compare(ours: np.ndarray, fx: Fixture) -> list[str]:
    """Every feature (or pooled feature) whose distribution differs: one line per problem."""
    names = fx.feature_names
    up = _upstream_rows(fx)
    problems = []
    pooled_ours: dict[str, list[np.ndarray]] = {}
    pooled_up: dict[str, list[np.ndarray]] = {}
    for i, name in enumerate(names):
        if _listed(name, _rule(KEPT, fx.env_id, ())):
            continue
        col = ours[:, i]
        if name in fx.resets.constants:
            want = fx.resets.constants[name]
            err = float(np.max(np.abs(col - want)))
            if err > CONST_TOL.get(fx.env_id, {}).get(name, CONST_ATOL):
                problems.append(f"{name}: upstream constant {want!r}, ours off by {err:.3g}")
            continue
        bound = SETTLE_NOISE.get(fx.env_id, {}).get(name)
        if bound is not None:
            err = max(float(np.abs(col).max()), float(np.abs(up[name]).max()))
            if err > bound:
                problems.append(f"{name}: {err:.3g} beyond the settle noise bound {bound}")
            continue
        key = _group(name, fx.env_id)
        pooled_ours.setdefault(key, []).append(col)
        pooled_up.setdefault(key, []).append(up[name])
    for key, cols in pooled_ours.items():
        res = _resolution(key)
        raw = np.concatenate(cols)
        shift = float(_rule(HEIGHT_SHIFT, fx.env_id, 0.0))
        grid = 0.0  # where the rounding grid is anchored
        if key.endswith(".z") and shift:
            offset = float(np.median(np.concatenate(pooled_up[key])) - np.median(raw))
            raw = raw + float(np.clip(offset, -shift, shift))
            # Centre a rounding step on the common median, so that a pile resting within
            # 0.5 mm of it is not split between two steps differently on the two sides.
            grid = float(np.median(raw))
        a = np.round((raw - grid) / res) * res + grid
        b = np.round((np.concatenate(pooled_up[key]) - grid) / res) * res + grid
        lo, hi = min(a.min(), b.min()), max(a.max(), b.max())
        if hi - lo <= res + SETTLE_ATOL:
            continue  # both at rest at the same value, to the resolution
        tails = _listed(key, _rule(POOLED_TAILS, fx.env_id, ()))
        # The smaller sample sets the slack (upstream's is 30 seeds on the variants).
        n = min(ours.shape[0], min(len(c) for c in pooled_up[key]))
        share = max(RANGE_SLACK, 1.0 - RANGE_MISS ** (1.0 / n))
        # At least one rounding step (plus float noise: 0.93 - 0.92 is 0.010000000000000009).
        slack = max(share * (b.max() - b.min()), res) + SETTLE_ATOL
        if not tails and (abs(a.min() - b.min()) > slack or abs(a.max() - b.max()) > slack):
            ours_range = f"{a.min():.4g}..{a.max():.4g}"
            problems.append(f"{key}: range {ours_range} vs upstream {b.min():.4g}..{b.max():.4g}")
            continue
        ks, crit = ks_statistic(a, b), ks_critical(a.size, b.size, ALPHA)
        if ks > crit:
            problems.append(f"{key}: KS {ks:.3f} > {crit:.3f}")
    return problems


def _columns(env: gymnasium.Env[Any, Any], fx: Fixture) -> list[int]:
    """Where each of upstream's features is in our vector."""
    names = list(env.unwrapped.box_space.feature_names)  # type: ignore[attr-defined]
    return [names.index(f) for f in fx.feature_names]


def _to_ours(env: gymnasium.Env[Any, Any], fx: Fixture, vec: np.ndarray) -> np.ndarray:
    """Our state vector for upstream's ``vec`` (``EXTRA_FEATURES`` at 0)."""
    names = list(env.unwrapped.box_space.feature_names)  # type: ignore[attr-defined]
    out = np.zeros(len(names))
    out[_columns(env, fx)] = vec
    return out


def test_feature_names_are_upstreams(fixture: Fixture) -> None:
    env = kinder_core.make(fixture.env_id)
    extra = EXTRA_FEATURES.get(fixture.env_id, ())
    names = list(env.unwrapped.box_space.feature_names)
    assert [n for n in names if n not in extra] == fixture.feature_names
    assert all(n in names for n in extra)


def _record_distribution(
    record_property: RecordProperty, fx: Fixture, problems: list[str], num_ours: int
) -> None:
    left_out = [n for n in fx.feature_names if _listed(n, _rule(KEPT, fx.env_id, ()))]
    kept = len(left_out)
    compared = len(fx.feature_names) - kept
    if left_out:
        shown = ", ".join(left_out[:4]) + (", ..." if kept > 4 else "")
        record_property("conformance_kept", f"{kept} features left out ({shown}; module docstring)")
    record_property(
        "conformance_figures",
        f"{compared - len(problems)}/{compared} features"
        + (f" ({kept} kept out)" if kept else "")
        + f"; {num_ours} of our seeds against {fx.resets.num_seeds} of upstream's",
    )
    record_property(
        "conformance_tolerance",
        "values rounded to 1 mm, 1 mrad, 0.01 (quaternions, velocities); constants to "
        f"{CONST_ATOL:g}; ranges and KS at alpha {ALPHA:g}",
    )


def test_reset_distribution_matches_upstream(
    fixture: Fixture, record_property: RecordProperty
) -> None:
    env = kinder_core.make(fixture.env_id)
    ours = sample_resets(env, range(1000, 1030))
    problems = compare(ours[:, _columns(env, fixture)], fixture)
    _record_distribution(record_property, fixture, problems, 30)
    assert not problems


@pytest.mark.slow
@pytest.mark.skip_by_design(
    reason="the variants are recorded on 30 seeds: their test is the one above"
)
def test_reset_distribution_matches_upstream_on_100_seeds(
    fixture: Fixture, record_property: RecordProperty
) -> None:
    if fixture.env_id.removeprefix("kinder/").removesuffix("-v0") in VARIANT_IDS:
        pytest.skip("a variant: upstream recorded 30 seeds, compared by the 30-seed test")
    env = kinder_core.make(fixture.env_id)
    ours = sample_resets(env, range(1000, 1100))
    problems = compare(ours[:, _columns(env, fixture)], fixture)
    _record_distribution(record_property, fixture, problems, 100)
    assert not problems


def test_the_comparison_catches_a_shifted_region(fixture: Fixture) -> None:
    """The check is not vacuous: upstream's own samples pass, and moving one sampled position
    feature that is range-tested (an x where there is one) by 10 cm (or by a quarter of its
    range, where that is more; half of it where upstream recorded fewer than 50 seeds) fails."""
    up = _upstream_rows(fixture)
    names = fixture.feature_names
    n = min(len(v) for v in up.values())
    rows = np.array(
        [[up[f][k] if f in up else fixture.resets.constants[f] for f in names] for k in range(n)]
    )
    assert not compare(rows, fixture)
    shifted = rows.copy()
    tails = _rule(POOLED_TAILS, fixture.env_id, ())
    sampled = [f for f in names if f in up and not _listed(_group(f, fixture.env_id), tails)]
    moved = next((f for f in sampled if f.endswith(".x")), sampled[0])
    # 30 seeds (the variants) resolve a shift of half the range; 100 seeds a quarter.
    share = 0.25 if n >= 50 else 0.5
    shifted[:, names.index(moved)] += max(0.1, share * float(np.ptp(up[moved])))
    assert compare(shifted, fixture)


def _groups(names: list[str]) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {"base": [], "gripper": [], "arm": [], "objects": []}
    for i, n in enumerate(names):
        obj, feat = n.split(".", 1)
        if n.startswith("robot.pos_base"):
            out["base"].append(i)
        elif n == "robot.pos_gripper":
            out["gripper"].append(i)
        elif n.startswith("robot.pos_arm"):
            out["arm"].append(i)
        elif obj != "robot" and feat in ("x", "y", "z"):
            out["objects"].append(i)
    return out


def one_step_errors(fx: Fixture, **config: object) -> dict[str, np.ndarray]:
    """The largest error per feature group at every recorded step, each step replayed from
    upstream's state before it (``config``: Dynamic3DConfig fields)."""
    env = kinder_core.make(fx.env_id, **({"config": config} if config else {}))
    groups = _groups(fx.feature_names)
    columns = _columns(env, fx)
    errors: dict[str, list[float]] = {g: [] for g in groups}
    for traj in fx.trajectories:
        before = traj.init_state
        for k, action in enumerate(traj.actions):
            env.reset(options={"init_state": _to_ours(env, fx, before)})
            obs, *_ = env.step(action.copy())
            err = np.abs(np.asarray(obs, dtype=np.float64)[columns] - traj.states[k])
            for g, idx in groups.items():
                errors[g].append(float(err[idx].max()))
            before = traj.states[k]
    return {g: np.array(v) for g, v in errors.items()}


def record_step_errors(
    record_property: RecordProperty, errors: dict[str, np.ndarray], env_id: str
) -> None:
    """Record the one-step errors (median / max per group) and the tolerances they met."""
    wider = _rule(STEP_TOL_BY_ID, env_id, {})
    tol = {**STEP_TOL, **wider}
    steps = len(next(iter(errors.values())))
    if wider:
        record_property(
            "conformance_kept",
            "wider one-step tolerance for " + ", ".join(sorted(wider)) + " (module docstring)",
        )
    record_property(
        "conformance_figures",
        f"{steps} one-step replays; "
        + ", ".join(f"{g} {np.median(e):.2g}/{e.max():.2g}" for g, e in errors.items()),
    )
    record_property(
        "conformance_tolerance",
        "one step from upstream's state, median/max per group: "
        + ", ".join(f"{g} {m:g}/{x:g}" for g, (m, x) in tol.items()),
    )


def over_tolerance(
    errors: dict[str, np.ndarray], median: bool = True, env_id: str = ""
) -> dict[str, tuple[float, float]]:
    """The groups whose median (if ``median``) or maximum error exceeds ``STEP_TOL`` (or
    ``STEP_TOL_BY_ID``'s for ``env_id``): (median, max)."""
    tol = {**STEP_TOL, **_rule(STEP_TOL_BY_ID, env_id, {})}
    out = {}
    for g, e in errors.items():
        med, top = float(np.median(e)), float(e.max())
        if (median and med > tol[g][0]) or top > tol[g][1]:
            out[g] = (med, top)
    return out


@pytest.mark.slow
def test_one_step_transitions_match_upstream_within_tolerance(
    fixture: Fixture, record_property: RecordProperty
) -> None:
    assert fixture.trajectories
    errors = one_step_errors(fixture)
    record_step_errors(record_property, errors, fixture.env_id)
    over = over_tolerance(errors, env_id=fixture.env_id)
    assert not over, f"{fixture.env_id}: one-step errors (median, max) over tolerance: {over}"


def test_first_steps_match_upstream_within_tolerance(
    fixture: Fixture, record_property: RecordProperty
) -> None:
    """The fast part: the first 5 steps of the first trajectory, replayed one step at a time
    (maximum errors only: 5 steps are too few for a median)."""
    traj = fixture.trajectories[0]
    first = replace(
        traj,
        actions=traj.actions[:5],
        states=traj.states[:5],
        rewards=traj.rewards[:5],
        terminated=traj.terminated[:5],
    )
    short = replace(fixture, trajectories=[first])
    errors = one_step_errors(short)
    record_step_errors(record_property, errors, fixture.env_id)
    over = over_tolerance(errors, median=False, env_id=fixture.env_id)
    assert not over, f"{fixture.env_id}: one-step errors (median, max) over tolerance: {over}"


#: Tolerances with upstream's arm controller (``arm_control="held_torque"``): (median, max).
#: Measured on Shelf3D-o1: arm median 4.8e-4, max 8.5e-3 rad (the gripper's own model differs;
#: the base and objects as with the default controller).
HELD_TORQUE_ARM_TOL = (2e-3, 0.02)


def test_upstreams_arm_controller_follows_upstream_closely() -> None:
    """With ``arm_control="held_torque"`` (upstream's torque held over the action, its joint
    damping) the arm's one-step error falls from about 0.03 rad to 5e-4 rad (median)."""
    fx = load_fixture(DATA / "Shelf3D-o1.json")
    short = replace(fx, trajectories=[replace(t, actions=t.actions[:10]) for t in fx.trajectories])
    held = one_step_errors(short, arm_control="held_torque")["arm"]
    default = one_step_errors(short)["arm"]
    assert float(np.median(held)) <= HELD_TORQUE_ARM_TOL[0]
    assert float(held.max()) <= HELD_TORQUE_ARM_TOL[1]
    assert float(np.median(default)) > 5 * float(np.median(held))
