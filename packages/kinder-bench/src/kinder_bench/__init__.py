"""kinder-bench."""
