"""Contacts between the body and the scene: the TRUMANS joint rule (``rule``) and per-frame runs
/ intervals, half-open ``[start, end)`` (``intervals``)."""
