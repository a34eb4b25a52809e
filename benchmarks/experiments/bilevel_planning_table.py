"""Write ``bilevel_planning.md``: bilevel planning (BP) results next to the paper's figures.

Reads the ``summary.csv`` of evaluation-runner directories (``kinder bench run ... --out DIR``)
and prints a markdown table of success rate, reward on successes and inference time per env,
with the paper's BP success and inference time beside them. Every figure comes from the CSVs.

    uv run python benchmarks/experiments/bilevel_planning_table.py RUN_DIR [RUN_DIR ...] \
        [--compare GBFS_RUN_DIR] > benchmarks/results/bilevel_planning.md
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

from kinder_bench.reporting.paper import load_paper


def _paper_bp() -> dict[str, tuple[float, str | None]]:
    """The paper's BP success rate and inference time (as printed) per env: Table II from the
    package's paper data file, then the StickButton2D scaling table (tab:planning_objects, SR
    only: its inference times were measured differently from Table II's)."""
    paper = load_paper()
    out: dict[str, tuple[float, str | None]] = {}
    for env in paper.envs:
        sr = paper.cells[(env, "BP", "SR")].mean
        out[env] = (0.0 if sr is None else sr, paper.cells[(env, "BP", "Inf-Time")].mean_text)
    out["kinder/StickButton2D-b3-v0"] = (0.26, None)
    out["kinder/StickButton2D-b5-v0"] = (0.02, None)
    out["kinder/StickButton2D-b10-v0"] = (0.00, None)
    return out


PAPER = _paper_bp()


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
