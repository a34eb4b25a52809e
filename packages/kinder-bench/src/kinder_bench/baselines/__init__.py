"""KinDERBench baselines beyond the agents package (bilevel planning)."""
