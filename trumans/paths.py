"""Where the repository keeps its shipped files: the trained models and the real-motion corpus.

The one place that knows the checkout's layout (``models/``, ``data/``); every default path of a
command is built from these.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["REPO_ROOT", "MODELS_DIR", "DATA_DIR"]

REPO_ROOT = Path(__file__).resolve().parents[1]
MODELS_DIR = REPO_ROOT / "models"  # generator.pt, refine.pt, contacts.pt, motion_encoder.pt, synthesis_reference.npz
DATA_DIR = REPO_ROOT / "data"  # mocap/cmu_corpus.npz
