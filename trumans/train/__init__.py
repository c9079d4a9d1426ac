"""Training: the task protocol and registry, the generator task, configs, data, the loop, DDP;
`trumans train` / `python -m trumans.train`."""
from trumans.train.config import GeneratorConfig, TrainConfig, load_config
from trumans.train.loop import TrainResult, train
from trumans.train.tasks import Task, TaskLoss, make_task, register_task, task_names

__all__ = ["GeneratorConfig", "TrainConfig", "load_config", "TrainResult", "train", "Task", "TaskLoss", "make_task",
           "register_task", "task_names"]
