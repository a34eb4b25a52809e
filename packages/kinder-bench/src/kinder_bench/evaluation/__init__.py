"""Evaluation: running agents on envs and keeping every result.

* ``runner.py``: the runner (:class:`~kinder_bench.evaluation.runner.RunConfig`,
  :func:`~kinder_bench.evaluation.runner.run_benchmark`), episode seeding and resuming;
* ``executors.py``: where episodes run (in process, a process pool, Ray);
* ``results.py``: a run directory's ``results.jsonl`` and ``config.json``;
* ``metrics.py``: the metrics and their one aggregation rule;
* ``summary.py``: a run's ``summary.csv`` rows;
* ``protocol.py``: the paper's evaluation protocol (envs, seeds, episodes, step budgets);
* ``envs.py``: looking up and making envs; ``recording.py``: episode videos.

These modules import nothing else of ``kinder_bench`` but the agent interface (``agents/``).
"""
