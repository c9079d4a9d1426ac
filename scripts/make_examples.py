"""Write the example files under examples/ (deterministic: same code, same files).

    python scripts/make_examples.py [--out examples]

- ``tracked_carry.npz``: a tracked human-object sequence, the input format of ``trumans refine``
  (docs/refine.md "Input"): CMU take 111_36 ("walk and carry", a held-out corpus subject) placed in its
  room with the box it carries (``trumans.synth.real_takes.real_sequence``), then corrupted by the
  tracker-error model ``trumans.refine.corrupt`` (jitter, drift, occluded joints and dropouts as NaN,
  object flips, IMU bias); ``tracked_carry_truth.npz`` is the clean sequence it came from.
- ``plan_sit_drink.toml``: a plan for ``trumans sample --plan`` in the default room.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from trumans.mocap_corpus import load_corpus
from trumans.refine.corrupt import add_clean_imu, corrupt
from trumans.refine.frame import frames_from_sequence, sequence_from_frames
from trumans.sequence import save_sequence
from trumans.synth.real_takes import real_sequence

CLIP = "111_36"
PLAN = """# trumans sample --plan examples/plan_sit_drink.toml --out out/plan   (the default room)
start = [2.4, 2.5]
heading = 0.0

[[steps]]
do = "sit_on"
object = "chair_0"
seconds = 6.0

[[steps]]
do = "stand_up"

[[steps]]
do = "goto"
to = [2.4, 3.4]

[[steps]]
do = "act"
action = "drink"
seconds = 3.0
"""


def tracked_example(seed: int = 0):
    """(tracked sequence with NaN = missing, the clean sequence) of the corpus take ``CLIP``."""
    (clip,) = [c for c in load_corpus(split="test") if c.name == CLIP]
    made = real_sequence(clip, seed)
    if made is None:
        raise RuntimeError(f"take {CLIP} fits no room; pick another take")
    clean, _ = made
    moving = {n: float(np.ptp(o.pose[:, :3, 3], axis=0).max()) for n, o in clean.objects.items()}
    name = max(moving, key=moving.get)  # the carried box
    clean.objects = {name: clean.objects[name]}
    frames, _ = frames_from_sequence(clean, name)
    frames = add_clean_imu(frames, clean.fps)
    noisy = corrupt(frames[None], clean.fps, np.random.default_rng(seed))[0]
    cat = clean.objects[name].category
    truth = sequence_from_frames(frames, clean.fps, name, cat, template=clean)
    tracked = sequence_from_frames(noisy, clean.fps, name, cat, imu=True)
    tracked.allow_missing = True
    tracked.validate()
    return tracked, truth


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "examples"))
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tracked, truth = tracked_example()
    save_sequence(tracked, out / "tracked_carry.npz")
    save_sequence(truth, out / "tracked_carry_truth.npz")
    (out / "plan_sit_drink.toml").write_text(PLAN)
    print(f"wrote {out}/tracked_carry.npz ({tracked.num_frames} frames at {tracked.fps:g} fps, object "
          f"{next(iter(tracked.objects))!r}), tracked_carry_truth.npz, plan_sit_drink.toml")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
