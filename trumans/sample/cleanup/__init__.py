"""The steps that change the body after the network (the sampler's cleanup): one ordered pipeline,
``pipeline.STEPS``, configured by ``pipeline.CleanupConfig`` and run by ``pipeline.run_cleanup``
(the order and why: ``trumans.sample.cleanup.pipeline``)."""
from trumans.sample.cleanup.pipeline import STEPS, CleanupConfig, CleanupStep, EpisodeBodies, run_cleanup

__all__ = ["STEPS", "CleanupConfig", "CleanupStep", "EpisodeBodies", "run_cleanup"]
