"""DPES on the paper's eight benchmark envs: train on each env's demonstrations, then evaluate.

Usage (resumable; see `learning_cells.py` for every option)::

    uv run python benchmarks/dpes.py                      # the paper's budget, all eight envs
    uv run python benchmarks/dpes.py --env Motion2D-p0 --seeds 0 --episodes 10 ...
"""

from __future__ import annotations

import sys

from learning_cells import main

if __name__ == "__main__":
    sys.exit(main("dpes"))
