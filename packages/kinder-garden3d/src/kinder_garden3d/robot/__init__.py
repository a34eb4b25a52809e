"""Robot model."""
