"""trumans: human-scene interaction motion (TRUMANS, I'm-HOI filter, iReplica tracking).

Core library: skeleton & rotations, sequences & actions, diffusion, networks, data, metrics.
"""
from .skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS, forward_kinematics, heading, rest_offsets
from .sequence import ObjectTrack, Sequence, load_sequence, save_sequence

__version__ = "0.1.0"
__all__ = [
    "JOINT_NAMES", "NUM_JOINTS", "PARENTS", "forward_kinematics", "heading", "rest_offsets",
    "ObjectTrack", "Sequence", "load_sequence", "save_sequence", "__version__",
]
