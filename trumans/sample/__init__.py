"""The generate job (TRUMANS §4): plans, the controller, the autoregressive sampler, the rollout,
moved objects, scene input, guidance terms and the post-network cleanup; ``trumans sample`` and
``trumans eval synthesis``. Installed as ``trumans.sample``."""
