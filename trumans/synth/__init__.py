"""Procedural synthetic HSI data: motion primitives, room scripts, labels, metrics."""
