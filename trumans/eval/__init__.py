"""Evaluation: the figures of every job (``metrics``, ``synthesis_metrics``), the motion
encoder behind FID / diversity / action accuracy (``motion_encoder``), and realism statistics
against real motion capture (``realism``; ``trumans eval realism``: ``realism_cli``)."""
