"""Contacts between the body and the scene: the TRUMANS joint rule (``rule``)."""
