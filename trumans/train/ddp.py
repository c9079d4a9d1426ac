"""Distributed data parallel helpers: the same command runs single-process or under ``torchrun``.

``torchrun --nproc_per_node N -m trumans.train ...`` sets RANK / WORLD_SIZE / LOCAL_RANK / MASTER_ADDR /
MASTER_PORT; ``setup()`` then joins the process group with NCCL on GPUs and gloo on CPUs.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import torch
import torch.distributed as dist

__all__ = ["DistInfo", "setup", "cleanup", "all_mean", "barrier"]


@dataclass(frozen=True)
class DistInfo:
    """rank / world: this process and the number of processes; device: where it computes."""

    rank: int = 0
    world: int = 1
    local_rank: int = 0
    device: torch.device = torch.device("cpu")

    @property
    def enabled(self) -> bool:
        return self.world > 1

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def setup(device: str | None = None) -> DistInfo:
    """Join the process group if WORLD_SIZE > 1 (torchrun); device: 'cpu', 'cuda', 'cuda:N' (one process
    only: under torchrun each process takes cuda:LOCAL_RANK) or None (cuda if available)."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    rank = int(os.environ.get("RANK", "0"))
    local = int(os.environ.get("LOCAL_RANK", str(rank)))
    index = device[5:] if device is not None and device.startswith("cuda:") else None
    if device not in (None, "cpu", "cuda") and not (index is not None and index.isdigit()):
        raise ValueError(f"device must be 'cpu', 'cuda' or 'cuda:N' (or None: cuda if available), got {device!r}")
    if index is not None:
        if world > 1:
            raise ValueError(f"--device {device}: under torchrun each process takes cuda:LOCAL_RANK; give --device cuda")
        local = int(index)
    use_cuda = torch.cuda.is_available() if device is None else device.startswith("cuda")
    if use_cuda and not torch.cuda.is_available():
        raise ValueError("device 'cuda' requested but CUDA is not available; use --device cpu")
    dev = torch.device(f"cuda:{local}") if use_cuda else torch.device("cpu")
    if use_cuda:
        torch.cuda.set_device(dev)
    if world > 1 and not dist.is_initialized():
        dist.init_process_group(backend="nccl" if use_cuda else "gloo")
    return DistInfo(rank, world, local, dev)


def cleanup(info: DistInfo, finished: bool = False) -> None:
    """Leave the process group. ``finished``: every rank got here normally, so they meet at a barrier
    first (gloo aborted now and then with "terminate called without an active exception" when one
    rank tore its connections down while the other was still in its last collective); after an
    error no barrier (the other ranks may never come)."""
    if info.enabled and dist.is_initialized():
        if finished:
            dist.barrier()
        dist.destroy_process_group()


def all_mean(value: float, info: DistInfo) -> float:
    """Mean of a float over all processes (the value itself when single-process)."""
    if not info.enabled:
        return float(value)
    t = torch.tensor([float(value)], dtype=torch.float64, device=info.device)
    dist.all_reduce(t)
    return float(t.item()) / info.world


def barrier(info: DistInfo) -> None:
    if info.enabled:
        dist.barrier()
