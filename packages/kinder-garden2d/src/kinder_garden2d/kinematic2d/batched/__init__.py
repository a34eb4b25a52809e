"""Batched Kinematic2D environments: N sub-envs of one id stepped in whole-array numpy.

* ``kernels``: the geometry kernels over a batch axis (and CPython's ``math.hypot``).
* ``world``: :class:`~.world.BatchedWorld`, the CRV transition over ``(N, D)`` states.
* ``families``: each family's goal, reward and extra rules.
* ``vector_env``: :class:`~.vector_env.Kinematic2DVectorEnv`, the Gymnasium vector env that
  every Kinematic2D id names as its ``vector_entry_point``.
"""
