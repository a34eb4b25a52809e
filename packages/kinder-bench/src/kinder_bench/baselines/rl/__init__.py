"""Model-free RL baselines: PPO and SAC on Stable-Baselines3 (KinDER spec, baselines §3.3).

* :mod:`~kinder_bench.baselines.rl.envs` — the training env stack (no torch import, so
  ``SubprocVecEnv`` workers stay light): step budget, optional dense reward, float32 observations,
  actions rescaled to [-1, 1], episode statistics.
* :mod:`~kinder_bench.baselines.rl.train` — ``PPOArgs``/``SACArgs`` (the paper's settings) and
  :func:`~kinder_bench.baselines.rl.train.train`, which checkpoints and resumes
  (``kinder train ppo|sac``).
* :mod:`~kinder_bench.baselines.rl.agents` — the ``ppo`` and ``sac`` agents that evaluate a
  checkpoint in the runner (``--arg checkpoint=DIR``).

Nothing here is imported by this ``__init__``: torch and SB3 load only when a trainer or an agent
is used. Install with ``pip install 'kinder-bench[rl]'``.
"""
