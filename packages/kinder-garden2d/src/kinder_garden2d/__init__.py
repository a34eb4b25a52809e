"""KinDERGarden 2D: the Kinematic2D (numpy geometry) and Dynamic2D (pymunk) environments.

Importing this package registers its ``kinder/...`` ids with gymnasium and does nothing else: no
simulator is imported and no environment variable is set until an environment is made.
"""

from kinder_garden2d.dynamic2d.registration import register_dynamic2d
from kinder_garden2d.kinematic2d.registration import register_kinematic2d

register_kinematic2d()
register_dynamic2d()

__all__ = ["register_dynamic2d", "register_kinematic2d"]
