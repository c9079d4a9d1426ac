"""Inverse kinematics on the 24-joint skeleton.

``fit`` (joint positions -> local rotations), ``limb`` (analytic two-bone limbs), ``ccd`` (vectorised
CCD with per-bone clipping, used by the augmentation; its sweeps in ``sweep``, on the component-major
arithmetic of ``soa``), ``rescale`` (copy a motion to other bone lengths).
"""
