"""trumans: human-scene interaction motion (TRUMANS, I'm-HOI filter, iReplica tracking).

Core library: skeleton & rotations, sequences & actions, diffusion, networks, data, metrics.
One-call API (``trumans.api``, imported on first use): ``generate``, ``refine_tracked``, ``track_interactions``.
"""
from .skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS, forward_kinematics, heading, rest_offsets
from .sequence import ObjectTrack, Sequence, load_sequence, save_sequence

from .version import __version__
__all__ = [
    "JOINT_NAMES", "NUM_JOINTS", "PARENTS", "forward_kinematics", "heading", "rest_offsets",
    "ObjectTrack", "Sequence", "load_sequence", "save_sequence", "__version__",
    "generate", "refine_tracked", "track_interactions",
]
_API = ("generate", "refine_tracked", "track_interactions")  # trumans.api, imported on first use (PEP 562)


def __getattr__(name: str):
    if name in _API:  # the API sits above every job: imported by name on first use, as trumans.scenes' names
        import importlib

        return getattr(importlib.import_module("trumans.api"), name)
    raise AttributeError(f"module 'trumans' has no attribute {name!r}")
