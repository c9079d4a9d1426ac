"""Guidance terms of the sampler (TRUMANS §4.1): gradients on the predicted clean motion."""
