"""Training of the generator: configs, data, loop, DDP; `trumans train` / `python -m train`."""
from .config import TrainConfig, load_config
from .loop import TrainResult, train

__all__ = ["TrainConfig", "load_config", "TrainResult", "train"]
