"""KinDERGarden 3D: the shared mobile-manipulator model, Kinematic3D (pybullet) and Dynamic3D
(MuJoCo) environments.

Importing this package registers its ids with gymnasium (via ``kinder_core.registration``) and
imports neither pybullet nor MuJoCo: environments are loaded through string entry points when
they are made. The robot model lives in :mod:`kinder_garden3d.robot`.
"""

from kinder_garden3d.kinematic3d.registry import register_kinematic3d

register_kinematic3d()

__all__ = ["register_kinematic3d"]

from kinder_garden3d.dynamic3d.registration import register_dynamic3d  # noqa: E402

register_dynamic3d()

from kinder_garden3d.limb3d.registry import register_limb3d  # noqa: E402

register_limb3d()
