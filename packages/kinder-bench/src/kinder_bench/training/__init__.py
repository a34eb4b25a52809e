"""The trainers' shared library: checkpoints, CSV progress logs and the weights' EMA (the
``kinder train`` commands are :mod:`kinder_bench.cli.train`).

Every trainer follows the same conventions so that runs look alike on disk:

* one output directory per run, holding ``config.json`` (the trainer's argument dataclass and the
  package versions), ``progress.csv`` (one row per logging interval, appended through
  :class:`~kinder_bench.training.csvlog.CsvLog`), and ``checkpoints/`` with periodic checkpoints
  written atomically, in the one format of every trainer (PPO, SAC, DP, DPES, MBRL, GSC):
  :mod:`~kinder_bench.training.checkpoints`;
* ``--resume`` (the default when the directory holds a checkpoint) continues from the last one;
* the agent that evaluates a trained policy takes ``--arg checkpoint=DIR`` and checks that the
  checkpoint was trained on a compatible env.
"""
