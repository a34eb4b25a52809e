"""Write ``bilevel_planning.md``: bilevel planning (BP) results next to the paper's figures.

Reads the ``summary.csv`` of evaluation-runner directories (``kinder bench run ... --out DIR``)
and prints a markdown table of success rate, reward on successes and inference time per env,
with the paper's BP success and inference time beside them. Every figure comes from the CSVs.

    uv run python benchmarks/results/bilevel_planning_table.py RUN_DIR [RUN_DIR ...] \
        [--compare GBFS_RUN_DIR] > benchmarks/results/bilevel_planning.md
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

# The paper's BP figures (success rate, inference time in s) and StickButton2D scaling.
PAPER = {
    "kinder/Motion2D-p0-v0": (1.00, 0.07),
    "kinder/StickButton2D-b1-v0": (0.99, 0.85),
    "kinder/DynObstruction2D-o1-v0": (0.08, 15.95),
    "kinder/DynPushPullHook2D-o5-v0": (0.01, 73.8),
    "kinder/BaseMotion3D-v0": (1.00, 0.02),
    "kinder/Transport3D-o2-v0": (0.46, 21.4),
    "kinder/Shelf3D-o1-v0": (1.00, 1.59),
    "kinder/SweepIntoDrawer3D-o5-v0": (0.03, 28.3),
    "kinder/StickButton2D-b3-v0": (0.26, None),
    "kinder/StickButton2D-b5-v0": (0.02, None),
    "kinder/StickButton2D-b10-v0": (0.00, None),
}


def _rows(run_dir: Path) -> list[dict[str, str]]:
    with open(run_dir / "summary.csv") as f:
        return list(csv.DictReader(f))


def _fmt(x: str, digits: int = 2) -> str:
    return f"{float(x):.{digits}f}"


def _search(run_dir: Path) -> str:
    config = json.loads((run_dir / "config.json").read_text())
    runs = config.get("runs", [])
    args = runs[0].get("agent_args", {}) if runs else {}
    return str(args.get("search", "astar"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="runner output directories")
    parser.add_argument("--compare", type=Path, help="a run with search=gbfs to compare")
    a = parser.parse_args()
    rows = [r for d in a.runs for r in _rows(d)]
    print("| env | seeds × episodes | SR | paper SR | Rwd (successes) | Inf-Time (s) | paper (s) |")
    print("|---|---|---|---|---|---|---|")
    for r in sorted(
        rows, key=lambda r: list(PAPER).index(r["env_id"]) if r["env_id"] in PAPER else 99
    ):
        sr_p, t_p = PAPER.get(r["env_id"], (None, None))
        paper_sr = "" if sr_p is None else f"{sr_p:.2f}"
        print(
            f"| {r['env_id']} | {r['num_seeds']} × {int(r['episodes']) // int(r['num_seeds'])} | "
            f"{_fmt(r['sr_mean'])} ± {_fmt(r['sr_std'])} | {paper_sr} | "
            f"{_fmt(r['rwd_mean'], 1)} | {_fmt(r['inf_time_mean'], 3)} ± "
            f"{_fmt(r['inf_time_std'], 3)} | {'' if t_p is None else t_p} |"
        )
    if a.compare is not None:
        print()
        print(f"Search comparison ({_search(a.compare)} vs astar, the same episodes: seed 0):")
        print()
        print("| env | search | SR | Inf-Time (s) |")
        print("|---|---|---|---|")
        gbfs = {r["env_id"]: r for r in _rows(a.compare)}
        for d in a.runs:
            for r in _rows(d):
                if r["env_id"] not in gbfs:
                    continue
                seed0 = _seed0(d, r["env_id"])
                g = gbfs[r["env_id"]]
                print(f"| {r['env_id']} | astar | {seed0[0]:.2f} | {seed0[1]:.3f} |")
                print(
                    f"| {r['env_id']} | {_search(a.compare)} | {_fmt(g['sr_mean'])} | "
                    f"{_fmt(g['inf_time_mean'], 3)} |"
                )


def _seed0(run_dir: Path, env_id: str) -> tuple[float, float]:
    """Success rate and mean inference time of seed 0 of one env in a run directory."""
    lines = (run_dir / "results.jsonl").read_text().splitlines()
    recs = [json.loads(line) for line in lines if line.strip()]
    recs = [r for r in recs if r["env_id"] == env_id and r["seed"] == 0]
    n = max(1, len(recs))
    return sum(r["success"] for r in recs) / n, sum(r["inference_time"] for r in recs) / n


if __name__ == "__main__":
    main()
