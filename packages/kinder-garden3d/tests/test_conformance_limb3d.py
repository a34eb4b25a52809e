"""LimbRepositioning3D conforms to upstream kindergarden 0.2.5, checked against recorded fixtures.

The fixtures (``tests/data/conformance/LimbRepositioning3D-<variant>.json`` for
isolated-right-arm, human-left-leg, wheelchair-left-arm and bed-left-leg) were recorded from
upstream with
``tools/conformance/record_upstream.py kinder/LimbRepositioning3D-<variant>-v0 --seeds 100
--full 10 --random 2 --steps 20 --no-scripts`` (upstream's IKFast module for the Kinova arm had
to be built against the shared LAPACK and BLAS libraries, which its build script expects as
static archives).

The family rule:

* Reset distributions: every feature conforms (base pose and goal constant and equal; each limb
  joint drawn from the same interval, by the KS and range tests of ``kinder_core.conformance``)
  except the arm joints: upstream solves the grasp with IKFast, taking the solution closest to
  its settled configuration, and we solve it with pybullet's damped least squares from the
  retract configuration, which lands on another branch of the 7-joint arm's solutions (same end
  effector pose, different joints). The wheelchair and bed variants start the solve from
  upstream's settled arm, so wheelchair-left-arm's arm joints conform too; bed-left-leg's do
  not (the solve leaves that start for another branch).
  bed-left-leg's hip abduction (``limb.joint_2``, the only joint its reset perturbs) does not
  conform either: upstream's draws lie within ±0.010 rad of the nominal start, ours within
  −0.025 to +0.005 rad, because the rejection of draws that press the leg deeper into the rest
  of the body depends on the body's shape, and upstream's mesh arms and legs sit closer to the
  lying leg than our primitive ones.
* One-step transitions, from each of upstream's recorded states under upstream's action: joint
  positions within ``POS_ATOL`` rad and joint velocities within ``VEL_ATOL`` rad/s; base pose
  and goal exactly. The limb and the robot are our primitive models, whose inertias differ from
  upstream's meshes and Kinova URDF, so one 1/240 s step under the same torques changes the
  velocities by slightly different amounts. Measured (40 steps each): isolated-right-arm,
  positions 2.3e-3 rad (robot joint 7; limb 2.5e-3, the wrist), velocities 0.59 rad/s (limb
  wrist) and 0.54 rad/s (robot joint 7); human-left-leg, positions 5.0e-4 rad, velocities
  0.12 rad/s; wheelchair-left-arm, positions 2.8e-3 rad and velocities 0.67 rad/s (both the limb
  wrist, ``limb.joint_5``); bed-left-leg, positions 5.0e-3 rad and velocities 1.20 rad/s (both
  robot joint 3), hence its wider bounds. The light distal links and the arm near a singular
  configuration carry the largest differences.

The scenes' other sides and limbs (``SLOW_VARIANTS``, recorded with ``--seeds 40 --full 5 --random
1 --steps 20 --no-scripts``) follow the same rule: only the arm joints' branch differs at reset,
and one step stays within the default bounds (measured: positions 2.2e-3 to 3.3e-3 rad on the
arms, 2.9e-4 to 8.2e-4 on the legs; velocities 0.52 to 0.79 rad/s on the arms, 0.069 to 0.20 on
the legs). The wheelchair legs conform too, with the seated person's shapes
(``limbs.limb_description(seated=True)``: the thighs' undersides and fuller hands, capsules fitted
to upstream's mesh hulls). The reset keeps a draw only if it brings the leg no more than 2 mm
closer to any body than the nominal start, so which piece of each body is nearest decides the
distribution: upstream's nearest pieces are the seat under the buttock (2.6 cm), the resting
hand on the same side (2.4 cm) and the other hand (33.3 cm from mid-thigh); without these
shapes ours were a wheelchair armrest corner (4.3 cm, 5.3 cm/rad with the hip flexion and 12
cm/rad with the abduction) and the other forearm's distance to the top of the hip (which the
leg's motion does not change), so our hip draws were 0.036 rad more flexed and the abduction
0.034 rad nearer the midline than upstream's. With them (distances 2.4, 1.9 and 33.8 cm),
against upstream's 300 draws (seeds 0-299, ours likewise; two-sample KS at most 0.17 on every
limb joint of either leg, critical 0.21): left leg ``limb.joint_1`` -1.277 [-1.315, -1.235]
against -1.282 [-1.329, -1.237], ``limb.joint_2`` -0.208 [-0.272, -0.180] against -0.203
[-0.255, -0.165]; right leg -1.274 [-1.314, -1.234] against -1.282 [-1.339, -1.235], 0.211
[0.182, 0.272] against 0.203 [0.153, 0.251]. Residual: our thigh capsule is round about its
axis, so rotating it about its length (``limb.joint_3``) changes none of its distances (upstream's
hull: -1.5, 3.8 and -1.4 cm/rad to the two hands and the seat; ours 0 to the hands, -2.1 to the
seat), and slightly fewer draws are rejected (90 % of the draws of the decaying noise against 91
%), so ``limb.joint_3`` to ``limb.joint_6`` spread 0.039 to 0.046 rad (standard deviation)
against upstream's 0.035 to 0.043. On the 40-seed fixtures the largest KS statistic is 0.40
(left ``limb.joint_1``; critical 0.50). One step stays within the default bounds (3.7e-4 and
4.5e-4 rad, 0.09 and 0.11 rad/s): the seated shapes are for the distance queries only, the
thigh keeps the plain limb's inertia.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import kinder_core
import kinder_garden3d  # noqa: F401  (registers the ids)
from kinder_core.conformance import RecordProperty, check_resets, load_fixture

DATA = Path(__file__).parent / "data" / "conformance"
VARIANTS = ["isolated-right-arm", "human-left-leg", "wheelchair-left-arm", "bed-left-leg"]
#: The scenes' other sides and limbs (``--seeds 40 --full 5 --random 1 --steps 20``), slow.
SLOW_VARIANTS = [
    "isolated-left-arm",
    "isolated-left-leg",
    "isolated-right-leg",
    "human-left-arm",
    "human-right-arm",
    "human-right-leg",
    "wheelchair-right-arm",
    "wheelchair-left-leg",
    "wheelchair-right-leg",
    "bed-left-arm",
    "bed-right-arm",
    "bed-right-leg",
]
ALL_VARIANTS = [*VARIANTS, *(pytest.param(v, marks=pytest.mark.slow) for v in SLOW_VARIANTS)]
#: One-step bounds: (positions in rad, velocities in rad/s); bed-left-leg's are wider.
DEFAULT_ATOL = (5e-3, 1.0)
ATOL = {"bed-left-leg": (7e-3, 1.5)}
#: The "exact" features (base pose, goal, fixture) to float rounding.
EXACT_ATOL = 1e-12
IK_BRANCH = {f"robot.joint_{i}" for i in range(1, 8)}
#: Features whose reset distribution differs, per variant (see the module docstring).
RESET_EXCEPTIONS = {
    "wheelchair-left-arm": set(),
    "bed-left-leg": IK_BRANCH | {"limb.joint_2"},
}


@pytest.mark.parametrize("variant", ALL_VARIANTS)
def test_reset_distribution(variant: str, record_property: RecordProperty) -> None:
    fixture = load_fixture(DATA / f"LimbRepositioning3D-{variant}.json")
    env = kinder_core.make(f"kinder/LimbRepositioning3D-{variant}-v0")
    try:
        report = check_resets(env, fixture)
    finally:
        env.close()
    allowed = RESET_EXCEPTIONS.get(variant, IK_BRANCH)
    failed = {f.name for f in report.failures}
    record_property("conformance_figures", report.summary())
    if failed:
        record_property(
            "conformance_kept",
            f"{sorted(failed)} differ (module docstring: the arm's IK branch"
            + (", the hip abduction's draws)" if "limb.joint_2" in failed else ")"),
        )
    assert failed <= allowed, [f for f in report.failures if f.name not in allowed]
    limb = [f for f in report.features if f.name.startswith("limb.joint_") and "vel" not in f.name]
    assert len(limb) == 6
    assert all(f.ok for f in limb if f.name not in allowed)
    fixture = [f for f in report.features if f.name.startswith("fixture.")]
    assert len(fixture) == (7 if variant.startswith(("wheelchair", "bed")) else 0)
    assert all(f.ok for f in fixture)


@pytest.mark.parametrize("variant", ALL_VARIANTS)
def test_one_step_transitions_from_upstream_states(
    variant: str, record_property: RecordProperty
) -> None:
    fixture = load_fixture(DATA / f"LimbRepositioning3D-{variant}.json")
    names = fixture.feature_names
    vel = np.array(["_vel_" in n for n in names])
    exact = np.array(
        [n.startswith(("robot.pos_base", "fixture.")) or ".goal_joint_" in n for n in names]
    )
    pos_atol, vel_atol = ATOL.get(variant, DEFAULT_ATOL)
    pos = ~vel & ~exact
    env = kinder_core.make(f"kinder/LimbRepositioning3D-{variant}-v0")
    steps = 0
    worst = np.zeros(2)
    try:
        for traj in fixture.trajectories:
            prev = traj.init_state
            for k, action in enumerate(traj.actions):
                env.reset(options={"init_state": prev.copy()})
                obs, reward, terminated, _, _ = env.step(action.copy())
                err = np.abs(np.asarray(obs) - traj.states[k])
                assert err[exact].max() <= EXACT_ATOL, (traj.name, k)
                assert err[pos].max() < pos_atol, (traj.name, k, names[int(np.argmax(err * pos))])
                assert err[vel].max() < vel_atol, (traj.name, k, names[int(np.argmax(err * vel))])
                assert reward == traj.rewards[k] and terminated == bool(traj.terminated[k])
                worst = np.maximum(worst, [err[pos].max(), err[vel].max()])
                prev = traj.states[k]
                steps += 1
    finally:
        env.close()
    record_property(
        "conformance_figures",
        f"{steps} one-step replays; positions max {worst[0]:.2g} rad, velocities max "
        f"{worst[1]:.2g} rad/s",
    )
    record_property(
        "conformance_tolerance",
        f"one step from upstream's state: joint positions {pos_atol:g} rad, velocities "
        f"{vel_atol:g} rad/s; base pose, goal and fixture to {EXACT_ATOL:g}",
    )
    assert steps == sum(len(t.actions) for t in fixture.trajectories) >= 20
