"""Side-by-side speed of our envs and the upstream ``kindergarden`` 0.2.5 package.

Creates ``.venv-upstream`` (once) with ``kindergarden==0.2.5`` from PyPI in its own virtual
environment, then runs ``env_speed.py`` for each id under both interpreters, alternating per id so
that machine load affects both alike, and prints a markdown table of ratios (ours / upstream for
steps/s; upstream / ours for reset and render times: > 1 means we are faster).

Usage:
    python benchmarks/upstream.py ID [ID ...] [--render] [--steps N] [--seconds S] [--repeats R]
        [--ours-kwargs JSON] [--upstream-kwargs JSON] [--out benchmarks/results/NAME.json]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
UPSTREAM_VENV = ROOT / ".venv-upstream"
UPSTREAM_SPEC = "kindergarden==0.2.5"
SPEED = Path(__file__).resolve().parent / "speed" / "env_speed.py"


def ensure_upstream_venv() -> Path:
    """The upstream venv's python, creating the venv on first use."""
    py = UPSTREAM_VENV / "bin" / "python"
    if py.exists():
        return py
    uv = shutil.which("uv") or f"{sys.executable} -m uv"
    subprocess.run(
        f"{uv} venv -q {UPSTREAM_VENV} --python {sys.executable}", shell=True, check=True
    )
    subprocess.run(f"{uv} pip install -q --python {py} {UPSTREAM_SPEC}", shell=True, check=True)
    return py


def run_speed(
    python: Path | str, env_id: str, args: argparse.Namespace, kwargs: str
) -> dict[str, Any]:
    cmd = [
        str(python), str(SPEED), env_id, "--steps", str(args.steps), "--seconds", str(args.seconds),
        "--make-kwargs", kwargs,
    ]  # fmt: skip
    if args.render:
        cmd.append("--render")
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    if str(python) != sys.executable:
        # Upstream forces MUJOCO_GL=osmesa when DISPLAY is unset (no OSMesa here, so it silently
        # registers no Dynamic3D ids) and downloads MimicLabs scenes unless told not to.
        env.setdefault("DISPLAY", ":99")
        env["DISABLE_AUTO_DYNAMIC3D_SCENES_DOWNLOAD"] = "1"
    with tempfile.TemporaryDirectory() as tmp:  # outside the repo: no workspace on the path
        out = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp, env=env)
    # Simulators may print to stdout without a newline (upstream pybullet prints "base_root"), so
    # take the last JSON object on any line.
    found = re.findall(r"\{.*\}", out.stdout)
    if not found:
        return {"env": env_id, "error": (out.stderr or out.stdout)[-400:]}
    rec: dict[str, Any] = json.loads(found[-1])
    return rec


def _median(recs: list[dict[str, Any]], key: str) -> float | None:
    vals = [r[key] for r in recs if key in r]
    return statistics.median(vals) if vals else None


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("ids", nargs="+")
    parser.add_argument("--render", action="store_true")
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=1, help="alternating runs per id (median)")
    parser.add_argument("--ours-kwargs", default="{}", help="JSON make kwargs for our ids")
    parser.add_argument("--upstream-kwargs", default="{}", help="JSON make kwargs for upstream")
    parser.add_argument("--out", type=Path, help="write the records as JSON here")
    args = parser.parse_args(argv)
    upstream_py = ensure_upstream_venv()
    ours_py = sys.executable
    rows = []
    records = []
    for env_id in args.ids:
        ours, theirs = [], []
        for _ in range(args.repeats):
            ours.append(run_speed(ours_py, env_id, args, args.ours_kwargs))
            theirs.append(run_speed(upstream_py, env_id, args, args.upstream_kwargs))
        records.append({"env": env_id, "ours": ours, "upstream": theirs})
        for side, recs in (("ours", ours), ("upstream", theirs)):
            for r in recs:
                if "error" in r:
                    print(f"{env_id} ({side}): {r['error']}", file=sys.stderr)
        o_sps, u_sps = _median(ours, "steps_per_s"), _median(theirs, "steps_per_s")
        o_rst, u_rst = _median(ours, "reset_s"), _median(theirs, "reset_s")
        o_rnd, u_rnd = _median(ours, "render_s"), _median(theirs, "render_s")
        rows.append((env_id, o_sps, u_sps, o_rst, u_rst, o_rnd, u_rnd))

    def f(v: float | None, spec: str) -> str:
        return "n/a" if v is None else format(v, spec)

    def ms(v: float | None) -> float | None:
        return None if v is None else 1e3 * v

    def ratio(a: float | None, b: float | None) -> str:
        return "n/a" if a is None or b is None or b == 0 else f"{a / b:.1f}x"

    print(
        "| env | steps/s ours | steps/s upstream | speed-up | reset ms ours | reset ms upstream "
        "| speed-up | render ms ours | render ms upstream | speed-up |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for env_id, o_sps, u_sps, o_rst, u_rst, o_rnd, u_rnd in rows:
        print(
            f"| {env_id} | {f(o_sps, '.0f')} | {f(u_sps, '.0f')} | {ratio(o_sps, u_sps)} "
            f"| {f(ms(o_rst), '.2f')} | {f(ms(u_rst), '.2f')} | {ratio(u_rst, o_rst)} "
            f"| {f(ms(o_rnd), '.2f')} | {f(ms(u_rnd), '.2f')} | {ratio(u_rnd, o_rnd)} |"
        )
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        tmp = args.out.with_suffix(".tmp")
        tmp.write_text(json.dumps(records, indent=1))
        tmp.replace(args.out)


if __name__ == "__main__":
    main()
