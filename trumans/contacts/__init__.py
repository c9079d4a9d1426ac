"""The TRUMANS contact rule between the body and the scene (TRUMANS §3.3, appendix B.5).

``rule`` the joint contact rule (signed distances of body points to the scene's objects);
``intervals`` per-joint contact intervals, half-open ``[start, end)``.
"""
