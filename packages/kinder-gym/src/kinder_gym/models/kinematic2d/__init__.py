"""Planning models of the Kinematic2D families."""
