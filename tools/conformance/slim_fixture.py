"""Shrink a recorded conformance fixture that is over the fixtures' 200 KB budget.

Scenes with dozens of objects (ScoopPour3D-o50, SweepSimple3D-o50) record a few hundred KB even
at 30 seeds. This keeps what the Dynamic3D checks use and drops the rest:

* the first ``--vectors`` full reset vectors (the seed-for-seed check is not run on Dynamic3D);
* each sampled feature's values on the first ``--seeds`` seeds, rounded to ``--decimals``
  (1e-4 by default, ten times finer than the comparison's 1 mm / 0.01 resolution);
* the first ``--steps`` steps of the first trajectory;
* the per-feature min / max / mean / std rounded one decimal finer.

Usage:
    python tools/conformance/slim_fixture.py IN.json OUT.json [--seeds 20] [--steps 3]

The output is written atomically; its size is printed. The fixture keeps the number of seeds
upstream was recorded on (``resets.num_seeds``); the samples say how many are stored.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path
from typing import Any


def slim(data: dict[str, Any], seeds: int, steps: int, vectors: int, decimals: int) -> None:
    """Shrink ``data`` (a fixture's JSON) in place."""
    if seeds < 1 or steps < 1 or vectors < 1:
        raise ValueError(f"seeds, steps and vectors must be >= 1, got {seeds}, {steps}, {vectors}")
    resets = data["resets"]
    resets["vectors"] = resets["vectors"][:vectors]
    resets["seeds"] = resets["seeds"][:vectors]
    resets["samples"] = {
        name: [round(float(v), decimals) for v in values[:seeds]]
        for name, values in resets["samples"].items()
    }
    for key in ("min", "max", "mean", "std"):
        resets[key] = [round(float(v), decimals + 1) for v in resets[key]]
    if not data["trajectories"]:
        raise ValueError("the fixture has no trajectories to keep")
    first = data["trajectories"][0]
    for key in ("actions", "deltas", "rewards", "terminated"):
        first[key] = first[key][:steps]
    data["trajectories"] = [first]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("source", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--seeds", type=int, default=20, help="seeds of samples kept")
    parser.add_argument("--steps", type=int, default=3, help="steps of the first trajectory kept")
    parser.add_argument("--vectors", type=int, default=1, help="full reset vectors kept")
    parser.add_argument("--decimals", type=int, default=4, help="samples rounded to 10^-decimals")
    args = parser.parse_args(argv)
    data = json.loads(args.source.read_text())
    if data.get("format") != 1:
        raise SystemExit(f"{args.source}: expected a format-1 conformance fixture")
    slim(data, args.seeds, args.steps, args.vectors, args.decimals)
    fd, tmp = tempfile.mkstemp(dir=args.out.parent, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(data, f, separators=(",", ":"))
    os.replace(tmp, args.out)
    print(f"{args.out}: {args.out.stat().st_size // 1024} KB")


if __name__ == "__main__":
    main()
