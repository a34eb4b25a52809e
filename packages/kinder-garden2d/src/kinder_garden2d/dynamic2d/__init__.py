"""Dynamic2D environments."""
