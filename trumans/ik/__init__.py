"""Inverse kinematics on the 24-joint skeleton.

``fit`` (joint positions -> local rotations), ``limb`` (analytic two-bone limbs), ``ccd`` (vectorised
CCD with per-bone clipping, used by the augmentation), ``rescale`` (copy a motion to other bone lengths).
"""
