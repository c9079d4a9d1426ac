"""Contacts between the body and the scene.

``rule`` the TRUMANS joint contact rule; ``intervals`` per-frame runs / intervals, half-open
``[start, end)``; iReplica's interaction tracking (§4): ``predictor`` the per-hand contact
transformer, ``per_dof`` one such model per dof class instead of the class head, ``labels`` its
training labels, ``model_io`` its checkpoints, ``postprocess``
thresholds / gap filling / contact segments, ``trajectory`` the bending-energy root correction,
``objects`` object motion driven by the hands, ``scores`` AP and friends.
"""
