"""The iReplica interaction tracker end to end (iReplica §4.1-4.3, supp. 10-11).

``predictor`` the per-hand contact transformer, ``per_dof`` one such model per dof class instead
of the class head, ``labels`` its training labels, ``model_io`` its checkpoints, ``postprocess``
thresholds / gap filling / contact segments, ``trajectory`` the bending-energy root correction,
``objects`` object motion driven by the hands within their degrees of freedom, ``object_choice``
which object a contact grasps, ``interactions`` the whole tracker, ``scores`` AP and friends,
``evaluate`` its benchmark (``trumans eval contacts``) and ``cli`` its front end
(``trumans track``).
"""
