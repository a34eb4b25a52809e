"""The table of the baselines' deviations from the paper (``kinder_bench/data/
baseline_deviations.csv``, rendered on docs/results.md)."""

from __future__ import annotations

import pytest

from kinder_bench.reporting.paper import load_paper
from kinder_bench.reporting.results_doc import deviations_markdown, load_deviations

HEADER = "baseline,what differs,why,expected effect\n"


def test_every_paper_baseline_has_a_row() -> None:
    named = {name.strip() for row in load_deviations() for name in row["baseline"].split("/")}
    missing = [m for m in load_paper().methods if m not in named]
    assert not missing, f"paper baselines without a deviations row: {missing}"


def test_every_row_is_rendered_once() -> None:
    rows = load_deviations()
    table = deviations_markdown().splitlines()
    assert len(table) == 2 + len(rows)
    for row, line in zip(rows, table[2:]):
        assert line.startswith(f"| {row['baseline']} | ")


def test_comments_are_skipped_and_pipes_escaped() -> None:
    text = "# a comment\n" + HEADER + 'VLA,"a | b",why,effect\n'
    assert load_deviations(text) == [
        {"baseline": "VLA", "what differs": "a | b", "why": "why", "expected effect": "effect"}
    ]
    assert "| VLA | a \\| b | why | effect |" in deviations_markdown(text)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("baseline,what differs,why\nBP,a,b\n", "expected the header"),
        ("", "expected the header"),
        (HEADER + "BP,a,b\n", "row 2 needs 4 non-empty fields"),
        (HEADER + "BP,a,,c\n", "row 2 needs 4 non-empty fields"),
    ],
)
def test_malformed_files_are_refused(text: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        load_deviations(text)
