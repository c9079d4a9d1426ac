"""The TRUMANS model family: diffusion, episode features, masks, networks and checkpoints."""
