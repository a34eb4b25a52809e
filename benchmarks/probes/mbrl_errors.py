"""The MBRL models' held-out open-loop errors, as a markdown table.

Reads ``eval.json`` of every run under ``RUNS`` (default ``runs/learning/mbrl/train``, written by
``benchmarks/experiments/learning.py mbrl`` or ``kinder train mbrl``): the mean L2 error of
the state after 1 and 10 open-loop steps on the recorded actions of the held-out episodes, raw
and in per-feature z-units, for the model and for the constant-state predictor (``s_{t+k} = s_t``).

Usage::

    uv run python benchmarks/probes/mbrl_errors.py [RUNS]
"""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _fmt(x: float) -> str:
    return "--" if x is None or math.isnan(x) else f"{x:.3g}"


def main() -> None:
    runs = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "runs/learning/mbrl/train"
    print(
        "| env | train transitions | epochs | held-out eps | 1-step L2 model / const | "
        "1-step z model / const | 10-step L2 model / const | 10-step z model / const | "
        "best val z (epoch) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for ev_path in sorted(runs.glob("*/eval.json")):
        ev = json.loads(ev_path.read_text())
        env = json.loads((ev_path.parent / "config.json").read_text())["env_id"]
        rows = list(csv.DictReader((ev_path.parent / "progress.csv").open()))
        scored = [r for r in rows if r["val_z_1"]]
        best = min(scored, key=lambda r: float(r["val_z_1"])) if scored else None
        cells = [
            env,
            str(ev["train_transitions"]),
            str(ev["epochs"]),
            str(len(ev.get("held_out_episode_seeds", []))),
        ]
        for k in (1, 10):
            for unit in ("l2", "z"):
                model = ev.get(f"model_{unit}_{k}", math.nan)
                const = ev.get(f"const_{unit}_{k}", math.nan)
                cells.append(f"{_fmt(model)} / {_fmt(const)}")
        cells.append(f"{float(best['val_z_1']):.3g} ({best['epoch']})" if best else "--")
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
