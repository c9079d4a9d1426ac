"""The I'm-HOI interaction diffusion filter end to end (I'm-HOI §3.2, appendix A.2): the
over-parameterised frame vector (``frame``), the corruption model with simulated object IMU
(``corrupt``), the windowing, the network wrapper (``filter``), the outlier flips, the post-steps
(``post_steps``: body drift, foot lock, object rests and hinges as one ordered pipeline with one
config), the inference pipeline (``pipeline``), its benchmark (``evaluate``) and the ``trumans
refine`` front end (``cli``)."""
from .corrupt import CorruptionConfig, add_clean_imu, corrupt, simulate_imu_acc
from .frame import (COND_DIM, FRAME_DIM, HOIFrames, condition_features, frames_from_sequence, from_frame,
                    pack_frames, resample_frames, sequence_from_frames, to_frame, unpack_frames, window_frame)
from .windows import blend_windows, window_starts, window_weights

__all__ = [
    "CorruptionConfig", "add_clean_imu", "corrupt", "simulate_imu_acc", "COND_DIM", "FRAME_DIM", "HOIFrames",
    "condition_features", "frames_from_sequence", "from_frame", "pack_frames", "resample_frames",
    "sequence_from_frames", "to_frame", "unpack_frames", "window_frame", "blend_windows", "window_starts",
    "window_weights",
]
