"""Record one upstream id into a conformance fixture; runs INSIDE the upstream venv.

``record_upstream.py`` launches this file with ``.venv-upstream/bin/python``. It imports only
``kinder`` (upstream kindergarden 0.2.5), ``gymnasium``, ``numpy`` and an optional scripts module
(numpy only), so it exercises upstream exactly as a user would. The fixture format is described in
``tools/conformance/README.md``.

Usage (one JSON request as the only argument):
    python upstream_worker.py '{"env_id": ..., "out": ..., "seeds": 200, "full": 20,
                                "random": 3, "steps": 60, "scripts": "path/or/null"}'
"""

from __future__ import annotations

import importlib.util
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import kinder
import numpy as np

Policy = Callable[[dict[str, float], int], "list[float] | None"]


def _full(values: Any) -> list[float]:
    """Exact floats: Python's repr of a float64 round-trips."""
    return [float(v) for v in np.asarray(values, dtype=np.float64).ravel()]


def _sig(values: Any, digits: int = 8) -> list[float]:
    """Floats to ``digits`` significant digits (distribution samples only)."""
    return [float(f"{float(v):.{digits}g}") for v in np.asarray(values, dtype=np.float64).ravel()]


class Upstream:
    """One upstream env with access to its internal float64 state."""

    def __init__(self, env_id: str) -> None:
        self.env = gym.make(env_id, allow_state_access=True)
        self.u = self.env.unwrapped
        space = self.u.observation_space
        self.objects = list(space.constant_objects)
        self.names = [f"{o.name}.{f}" for o in self.objects for f in space.type_features[o.type]]
        self.low = np.asarray(self.env.action_space.low, dtype=np.float64)
        self.high = np.asarray(self.env.action_space.high, dtype=np.float64)

    def state(self) -> np.ndarray:
        """The internal state (not the float32 observation) as a float64 vector."""
        s = self.u._object_centric_env.get_state()  # pylint: disable=protected-access
        return np.asarray(s.vec(self.objects, dtype=np.float64), dtype=np.float64)

    def reset(self, seed: int) -> np.ndarray:
        self.env.reset(seed=seed)
        return self.state()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool]:
        _, reward, terminated, _, _ = self.env.step(action.astype(self.env.action_space.dtype))
        return self.state(), float(reward), bool(terminated)


def record_resets(up: Upstream, num_seeds: int, num_full: int) -> dict[str, Any]:
    vecs = np.array([up.reset(seed) for seed in range(num_seeds)])
    const = np.all(vecs == vecs[0], axis=0)
    return {
        "num_seeds": num_seeds,
        "seeds": list(range(min(num_full, num_seeds))),
        "vectors": [_full(v) for v in vecs[:num_full]],
        "constants": {n: float(vecs[0, i]) for i, n in enumerate(up.names) if const[i]},
        "samples": {n: _sig(vecs[:, i]) for i, n in enumerate(up.names) if not const[i]},
        "min": _full(vecs.min(axis=0)),
        "max": _full(vecs.max(axis=0)),
        "mean": _full(vecs.mean(axis=0)),
        "std": _full(vecs.std(axis=0)),
    }


def run_trajectory(
    up: Upstream, name: str, kind: str, seed: int, policy: Policy, max_steps: int
) -> dict[str, Any]:
    state = up.reset(seed)
    init = state.copy()
    actions: list[list[float]] = []
    deltas: list[list[list[float]]] = []
    rewards: list[float] = []
    terminated: list[bool] = []
    for k in range(max_steps):
        raw = policy(dict(zip(up.names, state.tolist())), k)
        if raw is None:
            break
        action = np.clip(np.asarray(raw, dtype=np.float64), up.low, up.high)
        # Upstream's action space is float32; record the action it actually applies.
        action = action.astype(up.env.action_space.dtype).astype(np.float64)
        nxt, reward, term = up.step(action)
        changed = np.flatnonzero(nxt != state)
        actions.append(_full(action))
        deltas.append([[int(i), float(nxt[i])] for i in changed])
        rewards.append(reward)
        terminated.append(term)
        state = nxt
        if term:
            break
    return {
        "name": name,
        "kind": kind,
        "seed": seed,
        "init_state": _full(init),
        "actions": actions,
        "deltas": deltas,
        "rewards": rewards,
        "terminated": terminated,
    }


def random_policy(up: Upstream, gen_seed: int) -> Policy:
    rng = np.random.default_rng(gen_seed)

    def policy(state: dict[str, float], k: int) -> list[float]:
        del state, k
        return [float(v) for v in rng.uniform(up.low, up.high)]

    return policy


def compact(fixture: dict[str, Any], max_bytes: int) -> str:
    """The fixture as compact JSON, trimmed to ``max_bytes`` where it can be: first the full
    reset vectors down to 5, then the distribution samples to their first seeds (at least 40;
    ``num_seeds`` still counts every recorded seed, and min/max cover them all)."""
    resets = fixture["resets"]

    def dump() -> str:
        return json.dumps(fixture, separators=(",", ":"))

    text = dump()
    while len(text) > max_bytes:
        if len(resets["vectors"]) > 5:
            resets["vectors"] = resets["vectors"][:5]
            resets["seeds"] = resets["seeds"][:5]
        else:
            n = len(next(iter(resets["samples"].values()), []))
            keep = max(40, int(n * 0.8))
            if keep >= n:
                break
            resets["samples"] = {k: v[:keep] for k, v in resets["samples"].items()}
        text = dump()
    return text


def load_scripts(path: str) -> Any:
    spec = importlib.util.spec_from_file_location("conformance_scripts", path)
    assert spec is not None and spec.loader is not None, path
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    req = json.loads(sys.argv[1])
    kinder.register_all_environments()
    env_id = req["env_id"]
    up = Upstream(env_id)
    fixture: dict[str, Any] = {
        "format": 1,
        "env_id": env_id,
        "upstream": "kindergarden==" + req.get("upstream_version", "0.2.5"),
        "feature_names": up.names,
        "action_low": _full(up.low),
        "action_high": _full(up.high),
        "resets": record_resets(up, int(req["seeds"]), int(req["full"])),
    }
    trajectories = []
    for r in range(int(req["random"])):
        policy = random_policy(up, 1000 + r)
        trajectories.append(run_trajectory(up, f"random-{r}", "random", r, policy, req["steps"]))
    for plan in req.get("plans", []):
        # Actions planned in our package from the same seeded state (where our reset draws
        # upstream's initial state), replayed here from upstream's.
        actions = iter(plan["actions"])
        policy = lambda state, k, it=actions: next(it, None)  # noqa: E731
        trajectories.append(
            run_trajectory(
                up, plan["name"], "plan", int(plan["seed"]), policy, len(plan["actions"])
            )
        )
    if req.get("scripts"):
        module = load_scripts(req["scripts"])
        seeds = list(getattr(module, "SEEDS", [0, 1]))
        max_steps = int(getattr(module, "MAX_STEPS", 200))
        for seed in seeds:
            for name, policy in module.scripts(env_id, up.names).items():
                traj = run_trajectory(up, f"{name}-s{seed}", "scripted", seed, policy, max_steps)
                if traj["actions"]:
                    trajectories.append(traj)
    fixture["trajectories"] = trajectories
    text = compact(fixture, int(req.get("max_kb", 195)) * 1024)
    out = Path(req["out"])
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(json.dumps({"env_id": env_id, "out": str(out), "bytes": out.stat().st_size}))


if __name__ == "__main__":
    main()
