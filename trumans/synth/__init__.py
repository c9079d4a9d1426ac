"""Procedural synthetic HSI data: motion primitives, room scripts, labels, metrics.

``build`` writes the dataset; ``script`` performs takes of ``activities`` on a ``take.TakeState``
in a ``room.RoomContext``; the motion primitives are ``locomotion`` (with ``legs``, ``gait_plan``,
``footsteps``), ``posture`` and ``hands``; ``cases`` makes toy clips for tests and benchmarks.
"""
