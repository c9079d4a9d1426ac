"""Write the shipped motion encoder (models/motion_encoder.pt) as a checkpoint of kind "motion_encoder".

    python scripts/ship_motion_encoder.py runs/menc/checkpoint.pt --out models/motion_encoder.pt \
        --command "trumans train --task motion_encoder --data data/synth_v5 --out runs/menc"
    python scripts/ship_motion_encoder.py OLD.pt --out models/motion_encoder.pt

From a training run (``trumans train --task motion_encoder``): keeps the EMA weights as the model,
no optimiser state, the data record without the training machine's folder, the report figures
(``meta["figures"]``) and the training command. From a file of the retired private format
("trumans-motion-encoder-1", written by the trainer the task replaced): the same weights, input
mean / std, vocabulary and config, tensor for tensor, its report as ``meta["figures"]`` - no
retraining, so every figure measured with the old file holds for the new one. Either way the file
is read with ``weights_only`` (no code runs) and written with its digest.
"""
from __future__ import annotations

import argparse
import hashlib
import json
from dataclasses import replace
from pathlib import Path

import torch

from trumans.eval.motion_encoder import KIND, MotionEncoderConfig, encoder_checkpoint
from trumans.model.checkpoint import Checkpoint, load_checkpoint, save_checkpoint, shipped_data_record
from trumans.model.episodes import Normalizer

RETIRED_FORMAT = "trumans-motion-encoder-1"


def from_retired(path: Path, d: dict) -> Checkpoint:
    """The checkpoint of a retired-format dict ``d`` (read from ``path``): tensors as they are."""
    info = dict(d.get("info") or {})
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    data = {"name": info["data"], "hash": info["data_hash"]} if "data" in info and "data_hash" in info else {}
    return encoder_checkpoint(MotionEncoderConfig.from_dict(d["config"]), dict(d["state_dict"]),
                              Normalizer(d["mean"].numpy(), d["std"].numpy()), [str(v) for v in d["vocabulary"]],
                              data=data, meta={"figures": info, "converted_from": f"{RETIRED_FORMAT} file, sha256 {sha}"})


def export(ck: Checkpoint) -> Checkpoint:
    """A training run's checkpoint as a shipped file: the EMA weights as the model, no training state."""
    state = ck.ema_state if ck.ema_state is not None else ck.model_state
    return replace(ck, model_state=state, ema_state=None, train_state=None, data=shipped_data_record(ck.data))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint", help="a run's checkpoint.pt (kind motion_encoder) or a retired-format file")
    p.add_argument("--out", default="models/motion_encoder.pt")
    p.add_argument("--command", default="", help="the training command, recorded in meta (empty: not recorded)")
    a = p.parse_args(argv)
    path = Path(a.checkpoint)
    try:
        d = torch.load(path, map_location="cpu", weights_only=True)
        ck = from_retired(path, d) if isinstance(d, dict) and d.get("format") == RETIRED_FORMAT else \
            export(load_checkpoint(path, kind=KIND))
    except Exception as e:  # noqa: BLE001 - torch raises many types for a foreign file; one line, no trace
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        print(f"error: {path} is neither a motion encoder run's checkpoint nor a {RETIRED_FORMAT} file ({msg})")
        return 2
    if a.command:
        ck = replace(ck, meta={**ck.meta, "train_command": a.command})
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    save_checkpoint(a.out, ck)
    print(json.dumps({"out": a.out, "bytes": Path(a.out).stat().st_size,
                      "sha256": hashlib.sha256(Path(a.out).read_bytes()).hexdigest(),
                      "parameters": sum(v.numel() for v in ck.model_state.values()), "data": ck.data,
                      "figures": ck.meta.get("figures", {})}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
