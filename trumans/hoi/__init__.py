"""The HOI refinement filter's data side (I'm-HOI §3.2): the over-parameterised frame vector,
the corruption model with simulated object IMU, the regularisers and the windowing."""
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
