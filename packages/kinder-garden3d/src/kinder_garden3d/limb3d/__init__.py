"""LimbRepositioning3D (pybullet, dynamic): a robot drives a passive human limb to a goal
configuration with joint torques. The env is :mod:`kinder_garden3d.limb3d.env`; the limbs are
built from primitives in :mod:`kinder_garden3d.limb3d.limbs`."""
