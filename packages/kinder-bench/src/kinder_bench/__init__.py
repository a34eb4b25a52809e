"""KinDERBench: agents, the evaluation runner, metrics and reports, and the ``kinder`` CLI.

Where things are, top to bottom of the import layers (``[tool.importlinter]`` in the root
``pyproject.toml`` checks them):

* ``cli/``: the ``kinder`` command, one module per command group over ``cli/common.py``;
* ``demo.py`` (the showcase run) and ``campaign.py`` (experiment campaigns);
* ``baselines/``: every baseline, random and MPC included;
* three wings that do not import each other: ``reporting/`` (results tables, the paper
  comparison, the HTML report, ``docs/results.md``), ``demos/`` (demonstration collection, the
  datasets' specs and cards) and ``policy_server/``;
* ``evaluation/``: the runner, its executors, results files, metrics, ``summary.csv``, the paper's
  protocol, env lookup and videos;
* ``agents/`` (the interface the runner drives and the registry) and ``training/`` (the
  trainers' checkpoints and CSV logs).

>>> from kinder_bench import RunConfig, run_benchmark, write_report
>>> out = run_benchmark([RunConfig("kinder/Motion2D-p0-v0", "mpc", seeds=(0,), episodes=2)],
...                     "runs/example")                                   # doctest: +SKIP
>>> print(write_report(["runs/example"])[0])                              # doctest: +SKIP
"""

from kinder_bench.agents import (
    AGENTS,
    Agent,
    AgentFailure,
    NoArgs,
    agent_class,
    make_agent,
    register_agent,
)
from kinder_bench.baselines.mpc import MPCAgent, MPCArgs
from kinder_bench.baselines.random_agent import RandomAgent
from kinder_bench.evaluation.metrics import Stat, Summary, aggregate, summarize
from kinder_bench.evaluation.results import load_records
from kinder_bench.evaluation.runner import (
    BenchOutcome,
    EpisodeTask,
    RunConfig,
    episode_seeds,
    run_benchmark,
    run_episode,
)
from kinder_bench.evaluation.summary import csv_table
from kinder_bench.reporting.report import markdown_table, write_report

__version__ = "0.1.0"

__all__ = [
    "AGENTS",
    "Agent",
    "AgentFailure",
    "BenchOutcome",
    "EpisodeTask",
    "MPCAgent",
    "MPCArgs",
    "NoArgs",
    "RandomAgent",
    "RunConfig",
    "Stat",
    "Summary",
    "agent_class",
    "aggregate",
    "csv_table",
    "episode_seeds",
    "load_records",
    "make_agent",
    "markdown_table",
    "register_agent",
    "run_benchmark",
    "run_episode",
    "summarize",
    "write_report",
]
