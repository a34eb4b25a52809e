"""Does ``mujoco.rollout``, chained one env step at a time, reproduce Dynamic3D's ``transition``?

MPC's Dynamic3D fast path rolls candidates out on copies of the env instead (see
``kinder_bench/baselines/mpc.py``); this check backs what ``benchmarks/results/mpc.md`` says about
the alternative. From the state of ``--seed``, ``--steps`` random actions go through the env's
``transition`` and through ``mujoco.rollout`` (``substeps`` MuJoCo steps per env step, the
control the env's controller computes at the start of each env step, the fixtures' mocap poses
restored by hand because rollout states leave them out); the script prints the largest feature
difference, with the warm start zeroed (``--zero-warmstart``) or kept in the MjData between calls.

    uv run python benchmarks/probes/mujoco_rollout_check.py --env Shelf3D-o1 --steps 3
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np
from mujoco import rollout

from kinder_bench.evaluation.envs import make_env, resolve_env_id


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default="Shelf3D-o1")
    p.add_argument("--steps", type=int, default=3)
    p.add_argument("--seed", type=int, default=1000, help="Development seed (>= 1000).")
    p.add_argument("--zero-warmstart", action="store_true")
    args = p.parse_args()
    env = make_env(resolve_env_id(args.env))
    env.reset(seed=args.seed)
    m = env.unwrapped
    rng = np.random.default_rng(args.seed)
    low, high = m.action_space.low, m.action_space.high
    actions = [np.clip(rng.normal(size=low.shape) * 0.05, low, high) for _ in range(args.steps)]
    start = m.get_state()
    ref = start
    for a in actions:
        ref, _, _ = m.transition(ref, a)
    m._load(start)
    model, data = m.model, m.data
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    warm = data.qacc_warmstart.copy()
    mocap = data.mocap_pos.copy(), data.mocap_quat.copy()
    for k, a in enumerate(actions):
        mujoco.mj_setState(model, data, state, spec)
        data.mocap_pos[:], data.mocap_quat[:] = mocap
        m._apply(a)
        control = np.repeat(data.ctrl.copy()[None, None], m.config.substeps, axis=1)
        start_warm = warm[None] if k == 0 else None
        if k and args.zero_warmstart:
            start_warm = np.zeros((1, model.nv))
        out, _ = rollout.rollout(model, data, state[None], control, initial_warmstart=start_warm)
        state = out[0, -1]
    mujoco.mj_setState(model, data, state, spec)
    data.mocap_pos[:], data.mocap_quat[:] = mocap
    diff = np.abs(m._features() - ref.data).max()
    print(f"{args.env}, {args.steps} steps, seed {args.seed}, zero warm start "
          f"{args.zero_warmstart}: max |rollout - transition| = {diff}")  # fmt: skip


if __name__ == "__main__":
    main()
