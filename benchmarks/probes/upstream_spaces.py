"""Dump each KinDER id's observation/action space sizes and object/feature order, ours or upstream.

Runs under our workspace *and* under the upstream ``kindergarden`` venv (see ``upstream.py``); it
imports nothing of ours unconditionally. Every id is created with ``gymnasium.make`` as a new user
would; nothing is reset or stepped. For each id it records the observation and action shapes and,
where the observation space is an object-centric Box view (ours and upstream's), the objects in
vector order with their type name and feature names.

Usage:
    python benchmarks/probes/upstream_spaces.py --upstream \\
        --out benchmarks/results/upstream_spaces.json
        # creates .venv-upstream if needed and dumps upstream's spaces for each of our ids
    python benchmarks/probes/upstream_spaces.py --ours \\
        [--compare benchmarks/results/upstream_spaces.json]
        # dumps ours (to --out) and/or lists the ids whose sizes or orders differ
    python benchmarks/probes/upstream_spaces.py --worker ID \\
        [ID ...]   # (internal) one JSON line per id

The committed dump (``benchmarks/results/upstream_spaces.json``) is what
``packages/kinder-bench/tests/test_upstream_spaces.py`` pins our ids against, without network.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "benchmarks" / "results" / "upstream_spaces.json"


def _objects(space: Any) -> list[dict[str, Any]] | None:
    """(name, type, features) per object in vector order, for either side's Box view."""
    objs = getattr(space, "constant_objects", None)  # upstream (relational_structs)
    if objs is not None:
        tf = space.type_features
        return [{"name": o.name, "type": o.type.name, "features": list(tf[o.type])} for o in objs]
    objs = getattr(space, "objects", None)  # ours (kinder_core)
    if objs is not None:
        return [
            {"name": o.name, "type": o.type.name, "features": list(o.type.features)} for o in objs
        ]
    return None


def describe(env_id: str) -> dict[str, Any]:
    """One id's record (errors are recorded, not raised)."""
    import gymnasium

    rec: dict[str, Any] = {"env": env_id}
    try:
        try:
            registration = importlib.import_module("kinder_core.registration")
        except ImportError:
            importlib.import_module("kinder").register_all_environments()
        else:
            registration.ensure_registered(env_id)
        env = gymnasium.make(env_id, disable_env_checker=True)
        rec["obs_shape"] = list(env.observation_space.shape or ())
        rec["action_shape"] = list(env.action_space.shape or ())
        rec["objects"] = _objects(env.observation_space)
        env.close()
    except Exception as e:  # recorded for the report
        rec["error"] = f"{type(e).__name__}: {e}"[:400]
    return rec


def our_ids() -> list[str]:
    from kinder_core.registration import list_envs

    return list_envs()


def run_worker(python: str, ids: list[str]) -> list[dict[str, Any]]:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    if python != sys.executable:
        # Upstream forces MUJOCO_GL=osmesa when DISPLAY is unset (and then registers no Dynamic3D
        # ids here) and downloads MimicLabs scenes unless told not to.
        env.setdefault("DISPLAY", ":99")
        env["DISABLE_AUTO_DYNAMIC3D_SCENES_DOWNLOAD"] = "1"
    cmd = [python, str(Path(__file__).resolve()), "--worker", *ids]
    with tempfile.TemporaryDirectory() as tmp:  # outside the repo: no workspace on the path
        out = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp, env=env)
    # Simulators may print without a newline (upstream pybullet prints "base_root"): take each
    # line's JSON object wherever it starts.
    recs = [json.loads(m) for m in re.findall(r'\{"env": .*\}', out.stdout)]
    if len(recs) != len(ids):
        raise RuntimeError(
            f"worker returned {len(recs)} of {len(ids)} records: {out.stderr[-800:]}"
        )
    return recs


def compact(source: str, recs: list[dict[str, Any]]) -> dict[str, Any]:
    """The dump's file form: per id its sizes and ``[object, type, k]`` triples in vector order,
    ``k`` indexing the distinct feature lists (type names repeat across envs with other
    features)."""
    features: list[list[str]] = []
    envs: dict[str, Any] = {}
    for r in recs:
        if "error" in r:
            envs[r["env"]] = {"error": r["error"]}
            continue
        objs = []
        for o in r["objects"] or []:
            if o["features"] not in features:
                features.append(o["features"])
            objs.append([o["name"], o["type"], features.index(o["features"])])
        envs[r["env"]] = {"obs": r["obs_shape"], "action": r["action_shape"], "objects": objs}
    return {"source": source, "features": features, "envs": envs}


def expand(dump: dict[str, Any]) -> list[dict[str, Any]]:
    """The inverse of :func:`compact` (records as :func:`describe` returns them)."""
    recs = []
    for env_id, e in dump["envs"].items():
        if "error" in e:
            recs.append({"env": env_id, "error": e["error"]})
            continue
        objs = [{"name": n, "type": t, "features": dump["features"][k]} for n, t, k in e["objects"]]
        recs.append({"env": env_id, "obs_shape": e["obs"], "action_shape": e["action"],
                     "objects": objs or None})  # fmt: skip
    return recs


def write_json(path: Path, obj: dict[str, Any]) -> None:
    """One line per id (small diffs when a space changes), written atomically."""
    lines = [f'{{"source": {json.dumps(obj["source"])},', ' "features": [']
    lines += [f"  {json.dumps(f)}," for f in obj["features"]]
    lines[-1] = lines[-1].rstrip(",")
    lines += [" ],", ' "envs": {']
    items = list(obj["envs"].items())
    for k, (env_id, e) in enumerate(items):
        comma = "," if k < len(items) - 1 else ""
        lines.append(f"  {json.dumps(env_id)}: {json.dumps(e)}{comma}")
    lines.append("}}")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, path)


def compare(ours: list[dict[str, Any]], theirs: list[dict[str, Any]]) -> list[str]:
    """One line per id whose sizes, object order or features differ."""
    by_id = {r["env"]: r for r in theirs}
    lines = []
    for o in ours:
        u = by_id.get(o["env"])
        if u is None or "error" in u or "error" in o:
            lines.append(f"{o['env']}: {o.get('error') or (u or {}).get('error') or 'no upstream'}")
            continue
        diffs = []
        if o["obs_shape"] != u["obs_shape"]:
            diffs.append(f"obs {o['obs_shape']} vs upstream {u['obs_shape']}")
        if o["action_shape"] != u["action_shape"]:
            diffs.append(f"action {o['action_shape']} vs upstream {u['action_shape']}")
        if o["objects"] and u["objects"]:
            on = [x["name"] for x in o["objects"]]
            un = [x["name"] for x in u["objects"]]
            if on != un:
                diffs.append(f"objects {on} vs upstream {un}")
            of = [x["features"] for x in o["objects"]]
            uf = [x["features"] for x in u["objects"]]
            if on == un and of != uf:
                bad = [n for n, a, b in zip(on, of, uf, strict=True) if a != b]
                diffs.append(f"features differ for {bad}")
        if diffs:
            lines.append(f"{o['env']}: " + "; ".join(diffs))
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    side = parser.add_mutually_exclusive_group(required=True)
    side.add_argument("--upstream", action="store_true", help="dump upstream (kindergarden)")
    side.add_argument("--ours", action="store_true", help="dump ours")
    side.add_argument("--worker", nargs="+", metavar="ID", help=argparse.SUPPRESS)
    parser.add_argument("--ids", nargs="*", help="ids (default: every id we register)")
    parser.add_argument("--out", type=Path, help="write the records here (JSON)")
    parser.add_argument("--compare", type=Path, help="with --ours: an upstream dump to diff")
    args = parser.parse_args(argv)
    if args.worker:
        for env_id in args.worker:
            print(json.dumps(describe(env_id)), flush=True)
        return
    ids = args.ids or our_ids()
    if args.upstream:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from upstream import UPSTREAM_SPEC, ensure_upstream_venv

        recs = run_worker(str(ensure_upstream_venv()), ids)
        write_json(args.out or DEFAULT_OUT, compact(UPSTREAM_SPEC, recs))
    else:
        recs = run_worker(sys.executable, ids)
        if args.out:
            write_json(args.out, compact("ours", recs))
    errors = [r for r in recs if "error" in r]
    for r in errors:
        print(f"{r['env']}: {r['error']}", file=sys.stderr)
    if args.ours and args.compare:
        theirs = expand(json.loads(args.compare.read_text()))
        lines = compare(recs, theirs)
        print("\n".join(lines) if lines else "every id matches")
        print(f"{len(lines)} of {len(recs)} ids differ")


if __name__ == "__main__":
    main()
