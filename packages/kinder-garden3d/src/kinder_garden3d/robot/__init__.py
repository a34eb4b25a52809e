"""The KinDER mobile manipulator: TidyBot++ base, Kinova Gen3 arm, Robotiq 2F-85 gripper.

Modules (import them directly; this package imports nothing heavy):

* :mod:`~kinder_garden3d.robot.description` — the single source of truth
  (:func:`~kinder_garden3d.robot.description.robot_description`) and pure-numpy forward
  kinematics;
* :mod:`~kinder_garden3d.robot.urdf` — the generated URDF (pybullet);
* :mod:`~kinder_garden3d.robot.mjcf` — the generated MJCF (MuJoCo), standalone or as fragments;
* :mod:`~kinder_garden3d.robot.ik` — end-effector inverse kinematics with mink (needs MuJoCo).

Sources of every number are listed in this folder's ``README.md``.
"""

from kinder_garden3d.headless_gl import configure_headless_gl

# ik.py imports mujoco; MuJoCo fixes its GL backend at import, so choose a headless one first.
configure_headless_gl()
