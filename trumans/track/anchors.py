"""`trumans track --anchors FILE`: known floor positions of the body at some frames (iReplica's
trajectory correction takes them as hard anchors), read from an ``.npz`` holding ``frames`` (K,)
integer frame numbers and ``xy`` (K, 2) world metres.

Every way the file can be wrong is one clear error naming the file and the fix, checked before
the tracker runs: not a regular file, not an ``.npz`` archive (a ``.npy`` array, text), members
missing, Python objects (never unpickled), members declaring more than ``MAX_ANCHOR_BYTES``,
non-integer frames, non-finite positions, lengths that disagree.
"""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from trumans.input_files import check_input_file

__all__ = ["MAX_ANCHOR_BYTES", "read_anchors"]

MAX_ANCHOR_BYTES = 64 * 2**20  # one member: 4 M anchors of float64 xy, more than any sequence has frames
_FORM = "give an .npz with 'frames' (K,) integer frame numbers and 'xy' (K, 2) floor positions in m"


def read_anchors(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``(frames (K,) int64, xy (K, 2) float64 m)`` from the anchors file ``path`` (module doc);
    ValueError / FileNotFoundError naming the file and the fix."""
    p = check_input_file(path, "--anchors file", _FORM)
    where = f"--anchors {p}"
    try:
        z = np.load(p, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as e:
        why = "it holds Python objects or is no numpy file" if "pickle" in str(e) else " ".join(str(e).split())[:120]
        raise ValueError(f"{where} is not a readable .npz archive ({why}); {_FORM}") from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise ValueError(f"{where} is a single .npy array, not an .npz archive; {_FORM}")
    with z:
        missing = [k for k in ("frames", "xy") if k not in z.files]
        if missing:
            raise ValueError(f"{where} lacks {missing} (it has {z.files}); {_FORM}")
        arrays = {}
        for k in ("frames", "xy"):
            size = z.zip.getinfo(f"{k}.npy").file_size
            if size > MAX_ANCHOR_BYTES:
                raise ValueError(f"{where}: '{k}' is {size / 2**20:.0f} MiB, more than the limit of "
                                 f"{MAX_ANCHOR_BYTES / 2**20:.0f} MiB (trumans.track.anchors.MAX_ANCHOR_BYTES); {_FORM}")
            try:
                arrays[k] = z[k]
            except (ValueError, OSError, EOFError, zipfile.BadZipFile) as e:
                why = "it holds Python objects; unpickling is refused" if "pickle" in str(e) else str(e)[:120]
                raise ValueError(f"{where}: '{k}' is not a readable numeric array ({why}); {_FORM}") from None
    frames, xy = arrays["frames"], arrays["xy"]
    if frames.dtype.kind not in "iuf" or xy.dtype.kind not in "iuf":
        raise ValueError(f"{where} holds {frames.dtype} frames / {xy.dtype} xy, not numbers; {_FORM}")
    if frames.ndim != 1 or xy.shape != (len(frames), 2):
        raise ValueError(f"{where} holds frames {frames.shape} and xy {xy.shape}; they must be (K,) and (K, 2)")
    if not np.all(np.isfinite(frames)) or np.any(frames != np.round(frames)):
        raise ValueError(f"{where}: frames must be whole frame numbers, got {frames[:5].tolist()}...")
    xy = np.asarray(xy, np.float64)
    bad = ~np.all(np.isfinite(xy), axis=1)
    if bad.any():
        raise ValueError(f"{where}: xy of anchor {int(np.argmax(bad))} (frame {int(frames[np.argmax(bad)])}) is not "
                         f"finite ({xy[np.argmax(bad)].tolist()}); drop that anchor or give its position")
    return frames.astype(np.int64), xy
