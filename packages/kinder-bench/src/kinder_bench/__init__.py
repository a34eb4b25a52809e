"""KinDERBench: agents, the evaluation runner, metrics and reports, and the ``kinder`` CLI.

Where things are, top to bottom of the import layers (``[tool.importlinter]`` in the root
``pyproject.toml`` checks them):

* ``cli/``: the ``kinder`` command, one module per command group over ``cli/common.py``;
* ``demo.py`` (the showcase run) and ``campaign.py`` (experiment campaigns);
* ``baselines/``: every baseline, random and MPC included;
* reporting (``report.py``, ``paper.py``, ``html_report.py``, ``results_doc.py``),
  demonstrations (``demo_collection.py``, ``dataset_specs.py``, ``dataset_cards.py``) and
  ``policy_server/``, none of which imports another;
* evaluation: ``runner.py``, ``executors.py``, ``recording.py``, ``protocol.py``,
  ``metrics.py``, ``results.py``, ``summary.py``, ``envs.py``;
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
from kinder_bench.metrics import Stat, Summary, aggregate, summarize
from kinder_bench.report import markdown_table, write_report
from kinder_bench.results import load_records
from kinder_bench.runner import (
    BenchOutcome,
    EpisodeTask,
    RunConfig,
    episode_seeds,
    run_benchmark,
    run_episode,
)
from kinder_bench.summary import csv_table

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
