"""The steps that change the body after the network (the sampler's cleanup)."""
