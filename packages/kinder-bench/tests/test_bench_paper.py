"""The paper's data file, the paper comparison and the reports on a small fixture run."""

from __future__ import annotations

import csv
import dataclasses
import io
import itertools
import json
from importlib import resources
from pathlib import Path

import pytest
from typer.testing import CliRunner

from kinder_bench.agents import AGENTS, agent_class, unavailable_reason
from kinder_bench.cli import app
from kinder_bench.evaluation.metrics import Stat
from kinder_bench.evaluation.protocol import PAPER_ENVS, PAPER_MAX_STEPS, PAPER_SEEDS
from kinder_bench.evaluation.runner import RunConfig, run_benchmark
from kinder_bench.reporting.paper import (
    METRICS,
    NOT_IN_RUNS,
    NOT_RUN,
    PAPER,
    PRE_CONFORMANCE,
    VARIANTS_ONLY,
    Result,
    at_paper_protocol,
    compare,
    load_paper,
    load_pre_conformance,
    load_settings,
    paper_markdown,
    paper_settings,
    parse_paper,
    parse_pre_conformance,
    parse_settings,
    protocol_deviations,
    results_from_csv,
    variant_name,
)
from kinder_bench.reporting.report import write_report

MOTION = "kinder/Motion2D-p0-v0"
PAPER_METHODS = [
    "BP",
    "LLMCon",
    "VLMCon",
    "LLMPlan",
    "VLMPlan",
    "MPC",
    "VLA",
    "GSC",
    "DPES",
    "DP",
    "PPO",
    "MBRL",
    "SAC",
]  # Table II's columns, in order


def _data_text() -> str:
    return resources.files("kinder_bench.data").joinpath("paper_results.csv").read_text()


def test_paper_file_has_every_cell_exactly_once() -> None:
    text = _data_text()
    assert "Table II" in text and "tab:emp_all" in text and "tab:emp_std" in text
    rows = list(csv.DictReader(line for line in text.splitlines() if not line.startswith("#")))
    keys = [(r["env_id"], r["method"], r["metric"]) for r in rows]
    expected = set(itertools.product(PAPER_ENVS, PAPER_METHODS, METRICS))
    assert len(keys) == len(set(keys)) == len(expected) == 8 * 13 * 3
    assert set(keys) == expected
    paper = load_paper()
    assert paper.envs == PAPER_ENVS and paper.methods == tuple(PAPER_METHODS)
    assert len(set(paper.agents.values())) == 13
    assert paper.agents["BP"] == "bilevel_planning" and paper.agents["MPC"] == "mpc"
    # Spot checks against the paper, as printed.
    bp = paper.cells[(MOTION, "BP", "SR")]
    assert (bp.mean_text, bp.std_text, bp.mean, bp.std) == ("1.00", "0.000", 1.0, 0.0)
    vla = paper.cells[("kinder/StickButton2D-b1-v0", "VLA", "SR")]
    assert vla.text() == "0.53 ± 0.0676"
    assert paper.cells[(MOTION, "SAC", "Rwd")].mean is None
    assert paper.cells[("kinder/DynObstruction2D-o1-v0", "BP", "Rwd")].mean_text == "-68.62"


def test_parse_paper_rejects_bad_files() -> None:
    text = _data_text()
    lines = text.splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("kinder/"))
    with pytest.raises(ValueError, match="given twice"):
        parse_paper("\n".join([*lines, lines[first]]))
    with pytest.raises(ValueError, match="cells are missing"):
        parse_paper("\n".join(lines[:first] + lines[first + 1 :]))
    bad = lines[first].replace(",SR,1.00,", ",SR,one,")
    with pytest.raises(ValueError, match="neither a number"):
        parse_paper("\n".join([*lines[:first], bad, *lines[first + 1 :]]))
    bad = lines[first].replace(",SR,", ",Success,")
    with pytest.raises(ValueError, match="metric 'Success'"):
        parse_paper("\n".join([*lines[:first], bad, *lines[first + 1 :]]))
    bad = lines[first].replace(",bilevel_planning,", ",bp,")
    with pytest.raises(ValueError, match="maps to"):
        parse_paper("\n".join([*lines[:first], bad, *lines[first + 1 :]]))
    with pytest.raises(ValueError, match="header"):
        parse_paper("a,b\n1,2\n")


def test_agents_say_whether_they_can_run(monkeypatch: pytest.MonkeyPatch) -> None:
    from kinder_gym.models import MODELS

    bp = agent_class("bilevel_planning")
    assert bp.unavailable(bp.Args(), MOTION) is None
    monkeypatch.delitem(MODELS, "Dynamo3D", raising=False)  # a family without a model
    why = unavailable_reason("bilevel_planning", "kinder/Dynamo3D-o1-v0")
    assert why is not None and why.startswith("needs") and "Dynamo3D" in why
    assert unavailable_reason("mpc", MOTION) is None
    assert "registered" in (unavailable_reason("no_such_agent", MOTION) or "")
    assert "horizon" in (unavailable_reason("mpc", MOTION, {"horizon": "x"}) or "")


@pytest.fixture(scope="module")
def fixture_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small real run on Motion2D-p0: BP (in the paper), random (not in the paper, recorded as
    GIFs) and an agent that crashes every episode; MPC, StickButton2D etc. are missing cells."""
    run_dir = tmp_path_factory.mktemp("fixture") / "run"
    runs = [
        RunConfig(MOTION, "bilevel_planning", {}, (0, 1), 1),
        RunConfig(MOTION, "random", {}, (0, 1), 1, max_steps=8),
        RunConfig(MOTION, "kinder_bench_toy:CrashingAgent", {}, (0,), 1, max_steps=8),
    ]
    run_benchmark(
        runs,
        run_dir,
        executor="inline",
        record="gif",
        progress=False,
        command="kinder bench run (test fixture)",
    )
    return run_dir


def test_paper_report_on_a_fixture_run(fixture_run: Path, tmp_path: Path) -> None:
    md, paths = write_report([fixture_run], tmp_path, paper=True)
    assert paths["paper_table"].read_text() == md
    lines = md.splitlines()
    # The counts come first: nothing here is at the paper's protocol (2 seeds × 1 episode).
    assert lines[0] == "| The paper's 13 × 8 cells | count |"
    assert "| at the paper's protocol | 0 |" in lines
    assert "| variants only (listed under the table) | 1 |" in lines
    assert "| total | 104 |" in lines
    header = next(line for line in lines if line.startswith("| Env | Metric |"))
    assert "BP (bilevel_planning)" in header and "SAC (sac)" in header
    assert "random" not in header and "Crashing" not in header  # only the paper's columns
    sr = next(line for line in lines if line.startswith("| Motion2D-p0 | SR"))
    cells = [c.strip() for c in sr.split("|")[3:-1]]
    assert cells[0] == "var. (1.00 ± 0.000)"  # BP ran, but not at the paper's protocol
    assert cells[5].startswith("n/r [") and cells[5].endswith("(0.92 ± 0.050)")  # MPC
    assert NOT_IN_RUNS in md  # MPC can run here but is not in the runs
    for agent in ("llm_con", "dp", "ppo", "sac"):  # whatever these say when not run, it is there
        assert (unavailable_reason(agent, MOTION) or NOT_IN_RUNS) in md
    # Every run is a variant row, named by what differs from the paper's protocol.
    rows_md = [line for line in lines if line.startswith("| Motion2D-p0 | ") and "·" in line]
    names = [line.split("|")[2].strip() for line in rows_md]
    assert names[0].startswith("BP · 2×1, ") and "refinement_rounds=3" in names[0]
    assert "random · 2×1, 8 steps" in names
    assert any(n.startswith("kinder_bench_toy:CrashingAgent · 1×1") for n in names)
    # Every paper cell appears once in the CSV, with its status; a reason only when not run.
    rows = list(csv.DictReader(io.StringIO(paths["paper_csv"].read_text())))
    keys = {(r["env_id"], r["paper_method"], r["metric"]) for r in rows}
    assert len(rows) == len(keys) == 8 * 13 * 3
    for r in rows:
        assert r["status"] in (PAPER, VARIANTS_ONLY, NOT_RUN)
        assert bool(r["not_run_reason"]) == (r["status"] == NOT_RUN)
        assert (r["ours_seeds"] != "") == (r["status"] == PAPER)
        assert bool(r["variants"]) == (r["status"] == VARIANTS_ONLY)
    summary = list(csv.DictReader(io.StringIO(paths["csv"].read_text())))
    crash = next(r for r in summary if "Crashing" in r["agent"])
    assert crash["errors"] == "1" and crash["sr_mean"] == "0.0" and crash["seeds"] == "0"
    assert {r["command"] for r in summary} == {"kinder bench run (test fixture)"}
    bp = next(r for r in summary if r["agent"] == "bilevel_planning")
    assert bp["seeds"] == "0 1" and json.loads(bp["agent_args"])["refinement_rounds"] == 3


def test_the_runner_writes_the_summary_rows_into_the_run_directory(fixture_run: Path) -> None:
    """A run directory keeps its summary rows, so a committed copy needs no report run."""
    rows = list(csv.DictReader(io.StringIO((fixture_run / "summary.csv").read_text())))
    assert {r["agent"] for r in rows} == {
        "bilevel_planning",
        "random",
        "kinder_bench_toy:CrashingAgent",
    }
    assert all(r["command"] == "kinder bench run (test fixture)" for r in rows)
    assert {r["seeds"] for r in rows} == {"0 1", "0"}


def test_results_from_committed_csv_round_trip(fixture_run: Path, tmp_path: Path) -> None:
    _, paths = write_report([fixture_run], tmp_path)
    results = results_from_csv(paths["csv"])
    assert {r.agent for r in results} == {
        "bilevel_planning",
        "random",
        "kinder_bench_toy:CrashingAgent",
    }
    bp = next(r for r in results if r.agent == "bilevel_planning")
    assert bp.seeds == (0, 1) and bp.max_steps == 200 and bp.agent_args is not None
    md = paper_markdown(compare(results))
    assert "var. (1.00 ± 0.000)" in md
    bad = tmp_path / "bad.csv"
    bad.write_text("env_id,method\nx,y\n")
    with pytest.raises(ValueError, match="not a summary row"):
        results_from_csv(bad)


def _at_protocol(result: Result) -> Result:
    """``result`` as if run at the paper's protocol: seeds 0–4 × 50, the paper's budget and the
    agent's paper settings over its defaults."""
    args = {**(result.agent_args or {})}
    args.update(
        {
            k: v
            for k, v in paper_settings(result.agent, result.env_id).items()
            if k not in ("max_steps", "training")
        }
    )
    return dataclasses.replace(
        result,
        seeds=PAPER_SEEDS,
        num_seeds=5,
        episodes=250,
        max_steps=PAPER_MAX_STEPS[result.env_id],
        agent_args=args,
    )


def test_only_a_run_at_the_papers_protocol_fills_a_cell(fixture_run: Path, tmp_path: Path) -> None:
    _, paths = write_report([fixture_run], tmp_path)
    results = results_from_csv(paths["csv"])
    bp = _at_protocol(next(r for r in results if r.agent == "bilevel_planning"))
    assert protocol_deviations(bp) == () and at_paper_protocol(bp)
    comparison = compare([bp])
    (cell,) = [c for c in comparison.paper_cells() if c.env_id == MOTION and c.ours is not None]
    assert cell.column.paper_method == "BP" and cell.status == PAPER
    # Each recorded difference makes a variant, named by what differs.
    cases = {
        "5×10": {"episodes": 50},
        "seeds 5 6 7 8 9": {"seeds": (5, 6, 7, 8, 9)},
        "1×10, development seeds 1000": {"seeds": (1000,), "num_seeds": 1, "episodes": 10},
        "seeds not recorded": {"seeds": None},
        "100 steps": {"max_steps": 100},
        "step budget not recorded": {"max_steps": None},
        "args not recorded": {"agent_args": None},
        "refinement_rounds=3": {"agent_args": {**(bp.agent_args or {}), "refinement_rounds": 3}},
        "transcribed": {"provenance": "transcribed from x.md @ abc"},
    }
    for words, change in cases.items():
        variant = dataclasses.replace(bp, **change)  # type: ignore[arg-type]
        assert words in ", ".join(protocol_deviations(variant)), protocol_deviations(variant)
        assert not at_paper_protocol(variant)
        assert variant_name(variant) == f"BP · {words}"
        comparison = compare([variant])
        cell = comparison.cell(MOTION, comparison.columns[0], "SR")
        assert cell.status == VARIANTS_ONLY and cell.reason is None
        assert comparison.others == ((f"BP · {words}", variant),)
    # Settings a bool must match as a bool (1 is not true).
    flag = dataclasses.replace(bp, agent_args={**(bp.agent_args or {}), "replan_on_divergence": 0})
    assert protocol_deviations(flag) == ("replan_on_divergence=0",)
    # A learned agent must record the paper's training budget; MPC's per-env settings apply.
    ppo = dataclasses.replace(bp, agent="ppo", method="ppo", agent_args={"checkpoint": "c"})
    assert protocol_deviations(ppo) == ("training not recorded",)
    assert protocol_deviations(dataclasses.replace(ppo, training="1M env steps")) == ()
    sweep = "kinder/SweepIntoDrawer3D-o5-v0"
    mpc = _at_protocol(dataclasses.replace(bp, agent="mpc", method="mpc", env_id=sweep))
    assert paper_settings("mpc", sweep)["replan_interval"] == 50
    assert protocol_deviations(mpc) == ("500 steps",)  # upstream's Sweep config: 700 steps
    assert protocol_deviations(dataclasses.replace(mpc, max_steps=700)) == ()
    fm = _at_protocol(dataclasses.replace(bp, agent="llm_plan", method="llm_plan", agent_args={}))
    assert protocol_deviations(fm) == ()
    lines = dataclasses.replace(fm, agent_args={**(fm.agent_args or {}), "parameter_lines": True})
    assert variant_name(lines) == "LLMPlan · parameter_lines=true"


def test_a_run_measured_before_its_env_followed_upstream_is_a_variant(
    fixture_run: Path, tmp_path: Path
) -> None:
    _, paths = write_report([fixture_run], tmp_path)
    results = results_from_csv(paths["csv"])
    bp = _at_protocol(next(r for r in results if r.agent == "bilevel_planning"))
    listed = sorted(load_pre_conformance())
    assert listed and all(env != MOTION for _, env, _ in listed)  # Motion2D-p0 did not change
    run_id, env_id, summary = next(x for x in listed if x[1] in PAPER_MAX_STEPS)
    old = dataclasses.replace(
        _at_protocol(dataclasses.replace(bp, env_id=env_id)), run_id=run_id, summary=""
    )
    assert protocol_deviations(old) == (PRE_CONFORMANCE,) and not at_paper_protocol(old)
    from_file = dataclasses.replace(old, summary=summary)
    assert protocol_deviations(from_file) == (PRE_CONFORMANCE,)
    # The same run id on another env, another run on that env, or the same run made again on
    # the changed env (same run id, another summary file) is not listed.
    assert PRE_CONFORMANCE not in protocol_deviations(dataclasses.replace(old, run_id="0" * 12))
    again = dataclasses.replace(old, summary="a_later_summary.csv")
    assert PRE_CONFORMANCE not in protocol_deviations(again)
    header = "run_id,env_id,changed_at,summary\n"
    assert parse_pre_conformance(header + "# a comment\nabc,kinder/X-v0,78dd850,a.csv\n") == {
        ("abc", "kinder/X-v0", "a.csv")
    }
    with pytest.raises(ValueError, match="expected the header"):
        parse_pre_conformance("run,env\n")
    with pytest.raises(ValueError, match="data row 1"):
        parse_pre_conformance(header + "abc,kinder/X-v0,78dd850\n")
    # Every listed row is in the summary file it names.
    from kinder_bench.reporting.results_doc import summary_files

    held = {
        (r.run_id, r.env_id, r.summary)
        for f in summary_files(REPO / "benchmarks" / "results")
        for r in results_from_csv(f)
    }
    assert set(listed) <= held, sorted(set(listed) - held)


def test_the_paper_settings_file_is_checked() -> None:
    settings = load_settings()
    assert paper_settings("bilevel_planning", MOTION)["refinement_rounds"] == 1
    assert (
        paper_settings("bilevel_planning", "kinder/DynPushPullHook2D-o5-v0")["samples_per_step"]
        == 20
    )
    for (agent, _), values in settings.items():
        fields = {f.name for f in dataclasses.fields(agent_class(agent).Args)}
        assert set(values) - {"max_steps", "training"} <= fields, (agent, values)
    header = "agent,env_id,setting,value,source\n"
    with pytest.raises(ValueError, match="neither"):
        parse_settings(header + "mpc,kinder/Nope-v0,horizon,1,x\n")
    with pytest.raises(ValueError, match="not a JSON literal"):
        parse_settings(header + "mpc,*,search,astar,x\n")
    with pytest.raises(ValueError, match="given twice"):
        parse_settings(header + "mpc,*,horizon,1,x\nmpc,*,horizon,2,x\n")
    with pytest.raises(ValueError, match="header"):
        parse_settings("a,b\n")


def test_a_relabelled_variant_never_fills_the_paper_column(
    fixture_run: Path, tmp_path: Path
) -> None:
    _, paths = write_report([fixture_run], tmp_path)
    results = results_from_csv(paths["csv"])
    bp = _at_protocol(
        next(r for r in results if r.agent == "bilevel_planning" and r.env_id == MOTION)
    )
    # A variant of the same agent at the protocol, with more episodes (e.g. ppo-dense).
    variant = dataclasses.replace(
        bp,
        method="bilevel_planning-variant",
        run_id="f" * 12,
        success=Stat.of([0.25, 0.25]),
    )
    comparison = compare([bp, variant])
    md = paper_markdown(comparison)
    sr = next(line for line in md.splitlines() if line.startswith("| Motion2D-p0 | SR"))
    assert sr.split("|")[3].strip() == "**1.00 ± 0.000** (1.00 ± 0.000)"
    assert comparison.others == (("bilevel_planning-variant", variant),)
    # A run whose label only gained its run id (two runs of one label, other arguments) is the
    # agent's own, and fills the paper column when at the protocol.
    own = dataclasses.replace(variant, method="bilevel_planning[ffffff]")
    md = paper_markdown(compare([own]))
    sr = next(line for line in md.splitlines() if line.startswith("| Motion2D-p0 | SR"))
    assert sr.split("|")[3].strip() == "**0.25 ± 0.000** (1.00 ± 0.000)"


def test_html_report_in_headless_chromium(fixture_run: Path, tmp_path: Path) -> None:
    sync_api = pytest.importorskip("playwright.sync_api")
    chromium = Path("/usr/bin/chromium")
    if not chromium.exists():
        pytest.skip("Debian's chromium is not installed (tools/install_system_deps.sh)")
    _, paths = write_report([fixture_run], tmp_path, paper=True, html=True)
    page_text = paths["html"].read_text()
    assert "data:image/gif;base64," in page_text and "http://" not in page_text.replace(
        "http://www.w3.org/2000/svg", ""
    )
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=str(chromium), headless=True, args=["--no-sandbox"]
        )
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            problems: list[str] = []
            requests: list[str] = []
            page.on("console", lambda m: problems.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: problems.append(str(e)))
            page.on("request", lambda r: requests.append(r.url))
            page.goto(paths["html"].as_uri())
            page.wait_for_load_state("load")
            assert problems == []
            assert all(u.startswith(("file:", "data:")) for u in requests), requests
            rows = page.locator("#results tbody tr:not(.hidden)")
            assert rows.count() == 3  # BP, random, crashing (the not-run cells are hidden)
            assert page.locator("#plot rect[data-method]").count() == 3
            assert page.locator("figure img").count() == 3
            page.screenshot(path=str(tmp_path / "report.png"), full_page=True)
            # The method filter hides rows, bars and episodes of the unchecked method.
            page.locator("input[data-filter='method'][value='random']").uncheck()
            assert rows.count() == 2
            assert page.locator("#plot rect[data-method='random']").count() == 0
            assert page.locator("figure[data-method='random']:not(.hidden)").count() == 0
            assert page.locator("#shown").inner_text() == "2"
            # The paper's cells we did not run, for Motion2D-p0 only.
            page.locator("#show-notrun").check()
            page.locator("button[data-all='env'][data-on='0']").click()
            page.locator(f"input[data-filter='env'][value='{MOTION}']").check()
            assert rows.count() == 2 + 12  # the 12 paper methods other than BP
            assert page.locator("#results tbody tr.notrun:not(.hidden)").count() == 12
            page.screenshot(path=str(tmp_path / "report_filtered.png"))
            assert problems == []
        finally:
            browser.close()
    assert (tmp_path / "report.png").stat().st_size > 10_000


def test_cli_report_paper_and_html(fixture_run: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(
        app, ["bench", "report", str(fixture_run), "--out", str(tmp_path), "--paper", "--html"]
    )
    assert result.exit_code == 0, result.output
    assert "BP (bilevel_planning)" in result.output and "Not run:" in result.output
    assert "| variants only (listed under the table) | 1 |" in result.output
    assert (tmp_path / "report.html").exists() and (tmp_path / "paper_comparison.csv").exists()
    page = (tmp_path / "report.html").read_text()
    assert "<table id='counts'>" in page
    assert "<td>variants only (listed under the table)</td><td class='num'>1</td>" in page
    config = json.loads((fixture_run / "config.json").read_text())
    assert {r["command"] for r in config["runs"]} == {"kinder bench run (test fixture)"}


def test_bench_run_agent_all_skips_what_cannot_run(toy_id: str, tmp_path: Path) -> None:
    out_dir = tmp_path / "all"
    args = ["bench", "run", "--env", toy_id, "--agent", "all", "--import", "kinder_bench_toy"]
    args += ["--seeds", "0", "--episodes", "1", "--max-steps", "3", "--out", str(out_dir)]
    args += ["--executor", "inline", "--no-progress", "--arg", "horizon=3", "--no-report"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "skipping bilevel_planning on BenchReach: needs a planning model" in result.output
    config = json.loads((out_dir / "config.json").read_text())
    ran = {r["agent"] for r in config["runs"]}
    assert ran == {a for a in AGENTS if unavailable_reason(a, toy_id) is None}
    assert "random" in ran and "mpc" in ran
    # Naming an agent that cannot run is an error with the reason.
    named = ["bench", "run", "--env", toy_id, "--agent", "bilevel_planning"]
    named += ["--import", "kinder_bench_toy", "--out", str(tmp_path / "named")]
    result = CliRunner().invoke(app, named)
    assert result.exit_code == 2 and "needs a planning model" in result.output


def test_bench_run_label_names_a_variant(toy_id: str, tmp_path: Path) -> None:
    base = ["bench", "run", "--env", toy_id, "--import", "kinder_bench_toy", "--seeds", "0"]
    base += ["--episodes", "1", "--max-steps", "3", "--executor", "inline", "--no-progress"]
    out_dir = tmp_path / "variant"
    result = CliRunner().invoke(
        app, [*base, "--agent", "random", "--label", "random-variant", "--out", str(out_dir)]
    )
    assert result.exit_code == 0, result.output
    (row,) = csv.DictReader(io.StringIO((out_dir / "summary.csv").read_text()))
    assert (row["method"], row["agent"]) == ("random-variant", "random")
    # The training budget given to the run is recorded in the summary rows and config.json.
    trained = tmp_path / "trained"
    result = CliRunner().invoke(
        app, [*base, "--agent", "random", "--training", "1M env steps", "--out", str(trained)]
    )
    assert result.exit_code == 0, result.output
    (row,) = csv.DictReader(io.StringIO((trained / "summary.csv").read_text()))
    assert row["training"] == "1M env steps" and row["provenance"] == ""
    (run,) = json.loads((trained / "config.json").read_text())["runs"]
    assert run["training"] == "1M env steps"
    assert results_from_csv(trained / "summary.csv")[0].training == "1M env steps"
    two_agents = ["--agent", "random", "--agent", "mpc", "--label", "x"]
    blank_label = ["--agent", "random", "--label", " "]
    for bad in (two_agents, blank_label):
        result = CliRunner().invoke(app, [*base, *bad, "--out", str(tmp_path / "bad")])
        assert result.exit_code == 2 and "exactly one --agent" in result.output


REPO = Path(__file__).resolve().parents[3]


def test_results_doc_is_current_and_every_row_has_its_command(tmp_path: Path) -> None:
    from kinder_bench.reporting.results_doc import results_markdown, summary_files

    files = summary_files(REPO / "benchmarks" / "results")
    page = REPO / "docs" / "results.md"
    if not files or not page.exists():
        pytest.skip("not in the repository checkout")
    text = results_markdown(files, link_root=page.parent)
    assert page.read_text() == text, "docs/results.md is out of date: run `make results-doc`"
    assert "BP (bilevel_planning)" in text and "](#command-1)" in text
    bad = tmp_path / "bad_summary.csv"
    rows = (REPO / "benchmarks" / "results" / "bilevel_planning_summary.csv").read_text()
    header, first = rows.splitlines()[:2]
    cut = header.split(",").index("command")
    bad.write_text(
        ",".join(header.split(",")[:cut]) + "\n" + ",".join(first.split(",")[:cut]) + "\n"
    )
    with pytest.raises(ValueError, match="has no command"):
        results_markdown([bad], link_root=tmp_path)


def test_an_agent_that_needs_a_checkpoint(
    toy_id: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(AGENTS, "needs_checkpoint", "kinder_bench_toy:NeedsCheckpointAgent")
    monkeypatch.delenv("KINDER_BENCH_TEST_CHECKPOINT", raising=False)
    why = "needs a checkpoint: set KINDER_BENCH_TEST_CHECKPOINT"
    listing = CliRunner().invoke(app, ["agents"])
    assert listing.exit_code == 0 and "cannot run here on Motion2D-p0, " in listing.output
    assert why in listing.output
    args = ["bench", "run", "--env", toy_id, "--agent", "all", "--import", "kinder_bench_toy"]
    args += ["--seeds", "0", "--episodes", "1", "--max-steps", "2", "--executor", "inline"]
    args += ["--no-progress", "--no-report", "--arg", "horizon=2"]
    result = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "a")])
    assert result.exit_code == 0, result.output
    assert f"skipping needs_checkpoint on BenchReach: {why}" in result.output
    checkpoint = tmp_path / "ckpt"
    checkpoint.write_text("weights")
    monkeypatch.setenv("KINDER_BENCH_TEST_CHECKPOINT", str(checkpoint))
    result = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "b")])
    assert result.exit_code == 0, result.output
    config = json.loads((tmp_path / "b" / "config.json").read_text())
    assert "needs_checkpoint" in {r["agent"] for r in config["runs"]}


def test_suite_paper_with_agent_all_expands_to_what_can_run() -> None:
    from kinder_bench.cli.bench import _runnable, _suite_envs

    envs = _suite_envs("paper")
    assert envs and set(envs) <= set(PAPER_ENVS)
    pairs = _runnable(envs, ["all"], ["horizon=7"])
    expected = {(e, a) for e in envs for a in AGENTS if unavailable_reason(a, e, None) is None}
    assert {(e, a) for e, a, _ in pairs} == expected
    assert {(e, "bilevel_planning") for e in envs} <= expected  # BP models every paper env
    assert all(args == {"horizon": "7"} for _, a, args in pairs if a == "mpc")


def test_html_report_finds_the_videos_of_a_moved_run_directory(
    fixture_run: Path, tmp_path: Path
) -> None:
    import shutil

    moved = tmp_path / "moved"
    shutil.copytree(fixture_run, moved)
    lines = (moved / "results.jsonl").read_text().splitlines()
    records = [json.loads(line) for line in lines]
    for r in records:
        if r["video"]:
            r["video"] = f"gone/videos/{Path(r['video']).name}"  # where it was run from
    (moved / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    _, paths = write_report([moved], tmp_path / "out", plot=False, html=True)
    assert paths["html"].read_text().count("data:image/gif;base64,") == 3
