"""Planning models of the Dynamic2D families."""
