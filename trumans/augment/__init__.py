"""Contact-preserving motion augmentation (TRUMANS §3.3, appendix B.5): contact intervals, offset
blending (A1-A6), the two IK passes, object variations and the dataset pipeline. The CCD solver
lives in ``trumans.ik.ccd`` (re-exported here); contacts come from ``trumans.contacts``."""
from trumans.ik.ccd import IKConfig, IKResult, solve_ik
from trumans.augment.core import (AugmentConfig, AugmentOutput, SequenceContacts, augment_many, augment_sequence, find_intervals,
                   sequence_contacts, sequence_pose)
from trumans.augment.offsets import ContactInterval, Tracks, blend_tracks, contact_tracks, fade, handover, smooth_ratio
from trumans.augment.contact_ik import RetargetResult, retarget, retarget_many
from trumans.augment.variations import Variation, apply_variation, map_contact_points, sample_variation

__all__ = [
    "IKConfig", "IKResult", "solve_ik",
    "AugmentConfig", "AugmentOutput", "SequenceContacts", "augment_many", "augment_sequence", "find_intervals",
    "sequence_contacts", "sequence_pose",
    "ContactInterval", "Tracks", "blend_tracks", "contact_tracks", "fade", "handover", "smooth_ratio",
    "RetargetResult", "retarget", "retarget_many",
    "Variation", "apply_variation", "map_contact_points", "sample_variation",
]
