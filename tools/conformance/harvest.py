"""A pytest plugin that writes each conformance test's verdict to a JSON-lines file.

``table.py`` runs the conformance tests with ``-p harvest`` so that ``docs/conformance.md`` shows
what the tests decide, under the tests' own rules (tolerances, pooled features, kept
deviations), never a second comparison that could disagree with them. One line per test:

    {"nodeid": ..., "test": "test_transitions_match_upstream", "param": "StickButton2D-b1",
     "outcome": "passed" | "failed" | "xfailed" | "skipped" | "error", "slow": false,
     "message": ...,
     "properties": {"tolerance": ..., "figures": ..., "divergence": ..., "kept": ...}}

``properties`` are what the test recorded with pytest's ``record_property`` (the measured
figures and the tolerance it applied). The output path is ``$KINDER_CONFORMANCE_RESULTS``.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import pytest

_PARAM = re.compile(r"^(?P<test>[^\[]+)(?:\[(?P<param>.*)\])?$")


def _message(report: pytest.TestReport) -> str:
    """The failure's one-line reason (pytest's crash message), or the xfail reason."""
    if hasattr(report, "wasxfail"):
        return str(report.wasxfail).removeprefix("reason: ")
    crash = getattr(report.longrepr, "reprcrash", None)
    if crash is not None:
        return str(crash.message).splitlines()[0][:500]
    return str(report.longrepr).splitlines()[-1][:500] if report.longrepr else ""


class Harvest:
    """Collects the call-phase report of every test (and the setup report of a test that could
    not start)."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.lines: list[dict[str, Any]] = []

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when == "call" or (report.when == "setup" and not report.passed):
            name = report.nodeid.rsplit("::", 1)[-1]
            m = _PARAM.match(name)
            assert m is not None
            if hasattr(report, "wasxfail"):
                outcome = "xfailed"
            elif report.when == "setup" and report.failed:
                outcome = "error"
            else:
                outcome = report.outcome
            self.lines.append(
                {
                    "nodeid": report.nodeid,
                    "test": m.group("test"),
                    "param": m.group("param"),
                    "outcome": outcome,
                    "slow": "slow" in report.keywords,
                    "message": "" if report.passed else _message(report),
                    "properties": {
                        str(k).removeprefix("conformance_"): str(v)
                        for k, v in report.user_properties
                    },
                }
            )

    def pytest_sessionfinish(self) -> None:
        tmp = self.out.with_suffix(self.out.suffix + ".tmp")
        tmp.write_text("".join(json.dumps(line) + "\n" for line in self.lines))
        tmp.replace(self.out)


def pytest_configure(config: pytest.Config) -> None:
    out = os.environ.get("KINDER_CONFORMANCE_RESULTS")
    if not out:
        raise pytest.UsageError("harvest: set KINDER_CONFORMANCE_RESULTS to the output file")
    config.pluginmanager.register(Harvest(Path(out)), "kinder-conformance-harvest")
