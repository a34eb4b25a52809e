"""Test-run policy shared by every package's tests (pytest loads this file from the rootdir).

Under CI (the environment variable ``CI`` set to anything but ``""``, ``0`` or ``false``) a skipped
test is a failure: CI installs everything the tests need (``make test`` runs
``tools/install_system_deps.sh`` and syncs every extra), so a skip there means a missing browser,
npm package, system library or Python extra that would otherwise hide behind a green summary.
A skip that is part of a test's design (it can never run on this kind of machine, whatever is
installed) is marked ``@pytest.mark.skip_by_design(reason=...)`` and stays a skip. Outside CI every
skip prints its reason in the summary (``-ra`` in the root ``pyproject.toml``).
"""

from __future__ import annotations

import os
from collections.abc import Generator

import pytest


def _under_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "skip_by_design(reason): skip that is expected on every machine; never a CI failure",
    )


def _skip_reason(report: pytest.TestReport | pytest.CollectReport) -> str:
    longrepr = report.longrepr
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2])
    return str(longrepr)


def _fail_skip(report: pytest.TestReport | pytest.CollectReport) -> None:
    reason = _skip_reason(report)
    report.outcome = "failed"
    report.longrepr = (
        f"skipped under CI, where everything the tests need is installed: {reason}\n"
        "Install what it names (make test runs tools/install_system_deps.sh and syncs every "
        "extra), or mark a skip that holds on every machine with pytest.mark.skip_by_design."
    )


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(
    item: pytest.Item, call: pytest.CallInfo[None]
) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    report = yield
    if (
        report.skipped
        and _under_ci()
        and not hasattr(report, "wasxfail")
        and item.get_closest_marker("skip_by_design") is None
    ):
        _fail_skip(report)
    return report


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(
    collector: pytest.Collector,
) -> Generator[None, pytest.CollectReport, pytest.CollectReport]:
    report = yield
    if report.skipped and _under_ci():  # a module-level importorskip or skip
        _fail_skip(report)
    return report
