"""`trumans eval train CHECKPOINT`: recompute a checkpoint's validation loss on the val split."""
from __future__ import annotations

import argparse
from trumans.summary import print_summary
from trumans import argtypes
from trumans.checkpoint_args import add_checkpoint_arguments, resolve_checkpoint
from trumans.common_args import add_device_argument

__all__ = ["add_arguments", "run", "evaluate_checkpoint"]


def evaluate_checkpoint(path: str, data: str | None = None, ema: bool = True, seed: int = 0,
                        device: str = "cpu") -> dict:
    """{"val_loss", "val_loss_zero_baseline", "val_ratio", "val_episodes", "data_hash_match", ...}; the
    model and the diffusion run on ``device`` (batches are built on the CPU and moved there)."""
    import torch

    from trumans.model.checkpoint import load_checkpoint
    from trumans.dataset import Dataset

    from trumans.train.config import GeneratorConfig
    from trumans.train.data import BatchStream, load_episodes
    from trumans.train.tasks.generator import validation_loss

    torch.manual_seed(seed)
    ck = load_checkpoint(path)
    if ck.train_state is None or "config" not in ck.train_state:
        raise ValueError(f"{path} carries no training config; evaluate the RUN/checkpoint.pt written by `trumans train`")
    cfg = GeneratorConfig.from_dict(ck.train_state["config"], source=f"{path}'s training config")
    data = data or ck.data.get("path")
    if not data:
        raise ValueError(f"{path} does not record its dataset folder; pass --data DIR")
    ds = Dataset(data)
    if ds.vocabulary != ck.vocabulary:
        raise ValueError(f"{data} has action vocabulary {ds.vocabulary}, the checkpoint {ck.vocabulary}; "
                         f"evaluate on the data it was trained with")
    eps = load_episodes(ds, "val", cfg.data, ck.vocabulary, cache_dir=None)
    stream = BatchStream(eps, ck.normalizer, cfg.train.val_batch_size, seed)
    model = ck.build_model(ema=ema).to(device)
    v, z = validation_loss(model, ck.build_diffusion().to(device), stream, cfg)
    return {"val_loss": v, "val_loss_zero_baseline": z, "val_ratio": v / z if z > 0 else float("nan"),
            "val_episodes": min(len(eps), cfg.data.max_val_episodes), "ema": ema,
            "step": int(ck.train_state.get("step", -1)), "data_hash_match": (not ds.hash) or ds.hash == ck.data.get("hash"),
            "recorded_val_loss": ck.meta.get("val_loss"), "device": str(device)}


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_checkpoint_arguments(p, "RUN/checkpoint.pt written by `trumans train`")
    p.add_argument("--data", default=None, help="dataset folder (default: the one recorded in the checkpoint)")
    p.add_argument("--raw", action="store_true", help="evaluate the raw weights instead of the EMA weights")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (validation noise is fixed regardless)")
    add_device_argument(p, runs="the model and the diffusion; batches are read on the CPU")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object on the last line")


def run(args: argparse.Namespace) -> int:
    """Bad input raises ValueError / FileNotFoundError: the console script prints it as ``trumans: error: ...``."""
    if resolve_checkpoint(args) is None:
        raise ValueError("give the checkpoint to evaluate: --checkpoint RUN/checkpoint.pt")
    res = evaluate_checkpoint(args.checkpoint, args.data, ema=not args.raw, seed=args.seed, device=args.device)
    print(f"val loss {res['val_loss']:.4f} (zero baseline {res['val_loss_zero_baseline']:.4f}, "
          f"ratio {res['val_ratio']:.3f}) on {res['val_episodes']} episodes")
    if args.json:
        print_summary(res)
    return 0
