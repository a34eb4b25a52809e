"""Generate docs/results.md from the run summaries committed in benchmarks/results/.

Every ``benchmarks/results/*_summary.csv`` (with a ``command`` column) becomes a table, and all of
them fill the paper's Table II layout beside the paper's figures under one rule: a cell holds a
run at the paper's protocol, every other run is a labelled variant row, ``n/r`` says why and
how to run it; the page opens with the count of the paper's cells in each state and ends with
the baselines' deviations from the paper (:mod:`kinder_bench.reporting.results_doc`). ``--check``
fails when docs/results.md is out of date.

Usage:
    python tools/gen_results_doc.py            # write docs/results.md (= make results-doc)
    python tools/gen_results_doc.py --check    # exit 1 if it would change
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from kinder_bench.evaluation.results import write_text
from kinder_bench.reporting.results_doc import results_markdown, summary_files

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
PAGE = ROOT / "docs" / "results.md"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="fail if the page is out of date")
    args = parser.parse_args()
    text = results_markdown(summary_files(RESULTS), link_root=PAGE.parent)
    if args.check:
        if not PAGE.exists() or PAGE.read_text() != text:
            print(f"{PAGE} is out of date: run `make results-doc`", file=sys.stderr)
            return 1
        print(f"{PAGE} is up to date")
        return 0
    PAGE.parent.mkdir(parents=True, exist_ok=True)
    write_text(PAGE, text)
    print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
