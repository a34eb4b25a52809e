"""Kinematic2D environments."""
