"""Record upstream kindergarden 0.2.5's seeded resets and trajectories into conformance fixtures.

Runs with our venv's python; for each id it launches ``upstream_worker.py`` under the upstream venv
(``.venv-upstream``, created on first use by ``benchmarks/upstream.py``), which writes one JSON
fixture per id (format: ``tools/conformance/README.md``).

Usage:
    python tools/conformance/record_upstream.py ID [ID ...] | --family NAME
        [--out DIR] [--seeds N] [--full K] [--random R] [--steps S] [--scripts PATH | --no-scripts]

``--family`` takes a category (Kinematic2D, Dynamic2D, Kinematic3D, Dynamic3D) or a family name
(StickButton2D) and expands to our registered ids. Without ``--out`` each fixture goes to
``packages/<distribution>/tests/data/conformance/``; without ``--scripts`` the category's module
``tools/conformance/scripts/<category>.py`` is used when it exists.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import kinder_core  # noqa: E402
from benchmarks.upstream import ensure_upstream_venv  # noqa: E402
from kinder_core.conformance import fixture_name  # noqa: E402
from kinder_core.registration import CATEGORIES, FAMILY_SOURCES, list_envs  # noqa: E402

WORKER = Path(__file__).with_name("upstream_worker.py")
SCRIPTS = Path(__file__).with_name("scripts")


def family_of(env_id: str) -> str:
    """``kinder/StickButton2D-b1-v0`` -> ``StickButton2D``."""
    return env_id.split("/", 1)[1].split("-", 1)[0]


def expand_family(name: str) -> list[str]:
    """Our registered ids of a category or of one family."""
    if name in CATEGORIES:
        return list_envs(name)
    if name in FAMILY_SOURCES:
        return [i for i in list_envs(FAMILY_SOURCES[name].category) if family_of(i) == name]
    raise SystemExit(
        f"--family {name!r}: expected a category {list(CATEGORIES)} or a family "
        f"{sorted(FAMILY_SOURCES)}"
    )


def default_out(env_id: str) -> Path:
    dist = FAMILY_SOURCES[family_of(env_id)].distribution
    return ROOT / "packages" / dist / "tests" / "data" / "conformance"


def default_scripts(env_id: str) -> Path | None:
    path = SCRIPTS / f"{FAMILY_SOURCES[family_of(env_id)].category.lower()}.py"
    return path if path.exists() else None


def our_plans(env_id: str, num: int, timeout: float) -> list[dict[str, object]]:
    """Bilevel-planner plans made in our package from seeds 1000.. (analysis seeds): the
    worker replays each from upstream's state after the same seeded reset, which is our initial
    state only where our reset draws upstream's (see docs/conformance.md, seed for seed)."""
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_episode

    env = kinder_core.make_object_centric(env_id)
    plans: list[dict[str, object]] = []
    for seed in range(1000, 1000 + num):
        state, _ = env.reset(seed=seed)
        plan, _ = plan_episode(env, state, BilevelPlanningArgs(planning_timeout=timeout), seed)
        if plan is not None:
            actions = [[float(v) for v in a] for a in plan.actions]
            plans.append({"name": f"bp-s{seed}", "seed": seed, "actions": actions})
    return plans


def upstream_env() -> dict[str, str]:
    """The environment upstream needs here (see benchmarks/upstream.py's run_speed)."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    env.setdefault("DISPLAY", ":99")
    env["DISABLE_AUTO_DYNAMIC3D_SCENES_DOWNLOAD"] = "1"
    return env


def record(python: Path, env_id: str, out_dir: Path, args: argparse.Namespace) -> dict[str, object]:
    scripts = args.scripts if args.scripts is not None else default_scripts(env_id)
    if args.no_scripts:
        scripts = None
    request = {
        "env_id": env_id,
        "out": str((out_dir / fixture_name(env_id)).resolve()),
        "seeds": args.seeds,
        "full": args.full,
        "random": args.random,
        "steps": args.steps,
        "scripts": str(Path(scripts).resolve()) if scripts else None,
    }
    if args.plans:
        request["plans"] = our_plans(env_id, args.plans, args.plan_timeout)
    with tempfile.TemporaryDirectory() as tmp:  # outside the repo: no workspace on the path
        proc = subprocess.run(
            [str(python), str(WORKER), json.dumps(request)],
            capture_output=True,
            text=True,
            cwd=tmp,
            env=upstream_env(),
        )
    if proc.returncode != 0:
        raise RuntimeError(f"{env_id}: upstream worker failed:\n{proc.stderr[-2000:]}")
    # Upstream's pybullet robot prints "base_root" without a newline: a result line may carry
    # that prefix, so each line's JSON object is taken from where it starts.
    lines = [ln[ln.index('{"') :] for ln in proc.stdout.splitlines() if '{"' in ln]
    result: dict[str, object] = json.loads(lines[-1])
    return result


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("ids", nargs="*")
    parser.add_argument("--family", help="a category or a family name")
    parser.add_argument("--out", type=Path, help="fixture folder (default: the package's)")
    parser.add_argument("--seeds", type=int, default=200, help="seeded resets 0..N-1")
    parser.add_argument("--full", type=int, default=20, help="resets stored as full vectors")
    parser.add_argument("--random", type=int, default=3, help="random-action trajectories")
    parser.add_argument("--steps", type=int, default=60, help="steps per random trajectory")
    parser.add_argument("--scripts", type=Path, help="scripts module (numpy only)")
    parser.add_argument("--no-scripts", action="store_true", help="record no scripted runs")
    parser.add_argument("--plans", type=int, default=0, help="our BP plans (seeds 1000..)")
    parser.add_argument("--plan-timeout", type=float, default=60.0, help="seconds per plan")
    args = parser.parse_args(argv)
    ids = list(args.ids) + (expand_family(args.family) if args.family else [])
    if not ids:
        parser.error("give ids or --family")
    python = ensure_upstream_venv()
    for env_id in ids:
        out_dir = args.out if args.out is not None else default_out(env_id)
        res = record(python, env_id, out_dir, args)
        print(f"{env_id}: {res['out']} ({int(str(res['bytes'])) / 1024:.0f} KB)", flush=True)


if __name__ == "__main__":
    main()
