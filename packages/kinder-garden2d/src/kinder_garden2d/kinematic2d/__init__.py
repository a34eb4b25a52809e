"""Kinematic2D environments: a vacuum robot ("CRV") among rectangles, circles and L-shapes.

Modules (import them directly; importing this package imports nothing else):

* ``object_types``: types, z-order layers, colours.
* ``crv``: the robot's bodies, the world model (:class:`~.crv.KinematicWorld`) and the shared
  transition (move, carry suctioned objects, discard colliding proposals).
* ``predicates``: the goal predicates (``robot_in_region``, ``is_on``, ``is_inside``,
  ``is_inside_shelf``, ``is_pressed``, ``all_pressed``), shared with skills and planners.
* ``base``: :class:`~.base.Kinematic2DEnv` and the drawing of states.
* one module per family: ``motion2d``, ``obstruction2d``, ``clutteredretrieval2d``,
  ``clutteredstorage2d``, ``stickbutton2d``, ``pushpullhook2d``.
* ``batched``: N sub-envs of one id stepped in whole-array numpy, equal to the single env bit for
  bit (every id's ``vector_entry_point``).
* ``registration``: the registered ids.
"""
