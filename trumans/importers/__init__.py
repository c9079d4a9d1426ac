"""Importers of external data (TRUMANS release, BVH) into trumans types."""
