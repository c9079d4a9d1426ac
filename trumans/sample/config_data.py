"""Config dataclasses from plain data: moved to ``trumans.config_data`` (shared with the refine
post-steps, which must not import ``trumans.sample``); this name stays for the sampler's imports."""
from trumans.config_data import config_from_dict

__all__ = ["config_from_dict"]
