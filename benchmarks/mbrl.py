"""MBRL on the paper's eight benchmark envs: train on each env's demonstrations, then evaluate.

Usage (resumable; see `learning_cells.py` for every option)::

    uv run python benchmarks/mbrl.py                      # the paper's budget, all eight envs
    uv run python benchmarks/mbrl.py --env Motion2D-p0 --seeds 0 --episodes 10 ...

The paper's protocol for every baseline at once (MBRL's cells included, trained into the
campaign's own directory) is the campaign driver: ``uv run kinder bench campaign
benchmarks/campaigns/paper.toml --only mbrl`` (benchmarks/README.md, "Campaigns").
"""

from __future__ import annotations

import sys

from learning_cells import main

if __name__ == "__main__":
    sys.exit(main("mbrl"))
