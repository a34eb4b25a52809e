"""KinDERBench's baselines, one home for all: random, MPC, bilevel planning, the foundation-model
planners, VLA, diffusion policies, MBRL, GSC and RL. Each is an :class:`~kinder_bench.agents.Agent`
registered by name in :data:`kinder_bench.agents.AGENTS`."""
