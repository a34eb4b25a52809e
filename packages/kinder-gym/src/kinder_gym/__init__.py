"""kinder-gym."""
