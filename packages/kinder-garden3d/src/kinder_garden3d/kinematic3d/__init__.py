"""Kinematic3D environments: a mobile manipulator in pybullet, "teleport and check" dynamics.

Import the family modules (``base_motion3d``, ``obstruction3d``, ``packing3d``, ``table3d``,
``transport3d``) directly; this package itself imports nothing heavy, so registering the ids does
not load pybullet.
"""
