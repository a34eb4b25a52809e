"""Upstream's own replay noise on Dynamic2D fixtures (runs inside the upstream venv).

Upstream kindergarden 0.2.5 keeps one pymunk space alive through an episode, and Chipmunk's
hidden state (cached contact impulses, the robot bodies' small drift off their nominal layout) is
not in its state vector; reloading a state (``reset(options={"init_state": ...})``) drops it. Our
Dynamic2D envs rebuild the space from the state at every action, so each of our transitions should
equal upstream's "reload this state, then step". For every trajectory of a recorded fixture this
script writes ``dynamic2d_reload/<name>.json`` beside the fixture:

* ``reload``: upstream's reload-then-step result at a few steps of each trajectory (the first
  step, the steps where a ``held`` feature changes, and the last step), exact floats;
* ``replay_error``: per trajectory, the largest state error of upstream replaying the trajectory's
  actions after reloading its initial state once, against the recorded uninterrupted run (upstream's
  replay noise);
* ``onestep_error``: per trajectory, the largest error of upstream's reload-then-step against the
  uninterrupted run's next state (the noise a per-action reload adds).

Usage (our venv's python, from the repository root)::

    python tools/conformance/dynamic2d_reload.py \
        packages/kinder-garden2d/tests/data/conformance/DynObstruction2D-o1.json
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]

WORKER = r"""
import json, sys, warnings
import numpy as np
warnings.filterwarnings("ignore")
import gymnasium
import kinder

kinder.register_all_environments()
fx = json.loads(open(sys.argv[1]).read())
env = gymnasium.make(fx["env_id"])
u = env.unwrapped
oc = u._object_centric_env
objs = u.observation_space.constant_objects


def vec():
    st = oc._current_state
    return np.concatenate([np.asarray(st.data[o], dtype=np.float64) for o in objs])


env.reset(seed=0)
template = oc._current_state.copy()


def load(v):
    st = template.copy()
    i = 0
    for o in objs:
        n = len(st.data[o])
        st.data[o] = np.array(v[i : i + n], dtype=np.float64)
        i += n
    oc.reset(options={"init_state": st})


names = fx["feature_names"]
held = [i for i, n in enumerate(names) if n.endswith(".held")]
out = {"env_id": fx["env_id"], "reload": {}, "replay_error": {}, "onestep_error": {}}
for t in fx["trajectories"]:
    states, cur = [], np.array(t["init_state"], dtype=np.float64)
    for d in t["deltas"]:
        cur = cur.copy()
        for i, v in d:
            cur[int(i)] = v
        states.append(cur)
    if not states:
        continue
    prev = [np.array(t["init_state"])] + states[:-1]
    picks = {0, len(states) - 1}
    for k in range(1, len(states)):
        if any((states[k][i] > 0.5) != (prev[k][i] > 0.5) for i in held):
            picks.add(k)
    rel, worst = [], 0.0
    for k in range(len(states)):
        load(prev[k])
        oc.step(np.array(t["actions"][k]))
        v = vec()
        worst = max(worst, float(np.abs(v - states[k]).max()))
        if k in picks:
            rel.append([k, [float(x) for x in v]])
    out["reload"][t["name"]] = rel
    out["onestep_error"][t["name"]] = worst
    load(t["init_state"])
    err = 0.0
    for k, a in enumerate(t["actions"]):
        oc.step(np.array(a))
        err = max(err, float(np.abs(vec() - states[k]).max()))
    out["replay_error"][t["name"]] = err
open(sys.argv[2], "w").write(json.dumps(out, separators=(",", ":")))
"""


def main(argv: list[str]) -> None:
    if not argv:
        raise SystemExit(__doc__)
    py = ROOT / ".venv-upstream" / "bin" / "python"
    if not py.exists():
        raise SystemExit(f"{py} not found: create it with benchmarks/upstream.py first")
    env: dict[str, Any] = {
        **os.environ,
        "DISPLAY": os.environ.get("DISPLAY", ":99"),
        "DISABLE_AUTO_DYNAMIC3D_SCENES_DOWNLOAD": "1",
        "MUJOCO_GL": "egl",
    }
    for path in argv:
        fixture = Path(path).resolve()
        out = fixture.parent / "dynamic2d_reload" / fixture.name
        out.parent.mkdir(exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:  # outside the repo: no workspace on the path
            script = Path(tmp) / "worker.py"
            script.write_text(WORKER)
            subprocess.run(
                [str(py), str(script), str(fixture), str(out)], check=True, cwd=tmp, env=env
            )
        print(f"{fixture.name}: {out.name} ({out.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main(sys.argv[1:])
