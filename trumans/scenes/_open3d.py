"""open3d, imported when a scene query first needs it (not when ``trumans`` is imported).

Importing open3d costs about a second and needs a system library (``libusb-1.0``); code paths that
never cast a ray (a sampler without a scene, the refine filter, a checkpoint's inspection) should
neither pay that nor fail for it.
"""
from __future__ import annotations

import functools
from types import ModuleType

__all__ = ["open3d_module"]


@functools.cache
def open3d_module() -> ModuleType:
    """The ``open3d`` module; raises ImportError naming the fix when it cannot be imported."""
    try:
        import open3d
    except (ImportError, OSError) as e:  # a missing libusb-1.0 raises OSError
        raise ImportError(f"open3d could not be imported ({e}); scene queries need it: `pip install open3d` and, "
                          "on Debian/Ubuntu, `apt-get install libusb-1.0-0`") from e
    return open3d
