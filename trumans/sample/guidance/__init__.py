"""Guidance terms of the sampler (TRUMANS §4.1): costs on the predicted clean motion whose
gradients steer each denoising step (one protocol, ``base.GuidanceTerm``; the table, ``terms.TERMS``:
goal, seat, penetration; their config, ``terms.GuidanceConfig``)."""
from trumans.sample.guidance.base import GuidanceInputs, GuidanceTerm, Prediction
from trumans.sample.guidance.terms import TERMS, GuidanceConfig, TermSpec, build_terms

__all__ = ["GuidanceTerm", "Prediction", "GuidanceInputs", "TERMS", "TermSpec", "GuidanceConfig", "build_terms"]
