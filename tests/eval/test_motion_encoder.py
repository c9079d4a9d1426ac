"""trumans.eval.motion_encoder: windows, FID / diversity / accuracy, the network, the shipped weights."""
from __future__ import annotations


import numpy as np
import pytest
import torch

from trumans.eval.motion_encoder import (DEFAULT_MOTION_ENCODER, MotionEncoder, MotionEncoderConfig,
                                          MotionEncoderNet, action_acc, diversity, dominant_action, fid,
                                          like_sample, load_motion_encoder, matched_weights, motion_windows,
                                          save_motion_encoder, split_features)
from trumans.importers.bvh import import_bvh
from trumans.rotations import yaw_matrix
from trumans.skeleton import REST_JOINTS, heading
from trumans.synth.cases import make_case
from trumans.sample.sampler import SamplerConfig

from helpers import CMU_WALK_BVH


def _walk(T: int = 90, fps: float = 30.0, speed: float = 1.0) -> np.ndarray:
    """(T, 24, 3) rest pose (facing +x) moving forwards at ``speed`` m/s, legs swinging."""
    t = np.arange(T) / fps
    J = np.repeat(REST_JOINTS[None], T, 0).copy()
    J[:, :, 0] += speed * t[:, None]
    J[:, [4, 7, 10], 0] += 0.2 * np.sin(2 * np.pi * t)[:, None]
    J[:, [5, 8, 11], 0] -= 0.2 * np.sin(2 * np.pi * t)[:, None]
    return J.astype(np.float32)


def _tiny_encoder(seed: int = 0) -> MotionEncoder:
    torch.manual_seed(seed)
    cfg = MotionEncoderConfig(num_actions=3, window=8, channels=(8, 8, 8), feature_dim=6)
    rng = np.random.default_rng(seed)
    return MotionEncoder(cfg, MotionEncoderNet(cfg), rng.normal(0, 0.1, 144), rng.uniform(0.5, 1.5, 144),
                         ["stand", "walk", "sit"])


def test_fid_analytic_cases():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(400, 5)) @ rng.normal(size=(5, 5))
    assert fid(a, a) == pytest.approx(0.0, abs=1e-6)
    d = np.array([1.0, -2.0, 0.5, 0.0, 3.0])
    assert fid(a, a + d) == pytest.approx(float(d @ d), rel=1e-6)  # equal covariances: |mu_a - mu_b|^2
    # b = 2a: S_b = 4 S_a, (S_a S_b)^(1/2) = 2 S_a -> |mu_a|^2 + Tr(S_a)
    expect = float(a.mean(0) @ a.mean(0) + np.trace(np.cov(a, rowvar=False)))
    assert fid(a, 2 * a) == pytest.approx(expect, rel=1e-5)
    assert fid(a.reshape(20, 20, 5), a[::-1]) == pytest.approx(0.0, abs=1e-6)  # leading dims flatten
    with pytest.raises(ValueError, match="feature widths differ"):
        fid(a, a[:, :3])
    with pytest.raises(ValueError, match="at least 2 samples"):
        fid(a[:1], a)


def test_fid_matched_to_the_generated_action_mix():
    """Real windows: two actions 50/50 with distinct feature Gaussians; generated: the same two
    Gaussians mixed 90/10. Plain fid sees the mixture difference; weighted to the generated mix it
    is ~0. Integer weights give the fid of the set with those samples repeated."""
    rng = np.random.default_rng(1)
    A = rng.normal(size=(4000, 4))
    B = rng.normal(size=(4000, 4)) + [6.0, 0.0, 0.0, 0.0]
    real, real_y = np.concatenate([A[:2000], B[:2000]]), np.r_[np.zeros(2000, int), np.ones(2000, int)]
    gen, gen_y = np.concatenate([A[2000:3800], B[2000:2200]]), np.r_[np.zeros(1800, int), np.ones(200, int)]
    w = matched_weights(real_y, gen_y)
    assert w.sum() == pytest.approx(1.0) and w[:2000].sum() == pytest.approx(0.9)
    assert fid(real, gen) > 5.0
    assert fid(real, gen, real_weights=w) < 0.05
    assert fid(gen, real, gen_weights=w) == pytest.approx(fid(real, gen, real_weights=w), rel=1e-6)
    dup = np.concatenate([real[:500], real[:500], real[2000:2500]])
    wts = np.r_[np.full(500, 2.0), np.zeros(1500), np.ones(500), np.zeros(1500)]
    # reliability weights: the same mean, a covariance within the bias correction (~1e-3)
    assert fid(real, gen, real_weights=wts) == pytest.approx(fid(dup, gen), rel=2e-3)
    # actions only one side has: real windows of an action not generated get 0, a generated action
    # the real set lacks is left out; no shared action is an error
    w = matched_weights(np.r_[0, 0, 2, 2], np.r_[0, 1, 1])
    np.testing.assert_allclose(w, [0.5, 0.5, 0.0, 0.0])
    with pytest.raises(ValueError, match="no action of the generated windows"):
        matched_weights(np.r_[0, 0], np.r_[1, 1])
    with pytest.raises(ValueError, match="real_weights must be"):
        fid(real, gen, real_weights=np.ones(3))
    with pytest.raises(ValueError, match="gen_weights must be"):
        fid(real, gen, gen_weights=-np.ones(len(gen)))


def test_like_sample_draws_the_generated_size_and_mix_and_shows_the_small_set_bias():
    rng = np.random.default_rng(2)
    pool_y = np.r_[np.zeros(300, int), np.ones(100, int), np.full(5, 2)]
    idx = like_sample(pool_y, np.r_[np.zeros(20, int), np.ones(10, int), np.full(8, 2), np.full(3, 7)], rng)
    assert len(idx) == 38  # action 7 is not in the pool: left out
    np.testing.assert_array_equal(np.bincount(pool_y[idx]), [20, 10, 8])
    assert len(set(idx[:30].tolist())) == 30  # enough: without replacement; action 2 (5 < 8): with
    with pytest.raises(ValueError, match="no action of the generated windows"):
        like_sample(pool_y, np.r_[9, 9], rng)
    # the same Gaussian: fid of 40 draws against 4000 is far above that of 4000 (why the eval
    # reports the real-vs-real value at the generated set's size)
    real, pool = rng.normal(size=(4000, 16)), rng.normal(size=(4000, 16))
    small = pool[like_sample(np.zeros(4000, int), np.zeros(40, int), rng)]
    assert fid(real, pool) < 0.2 < 2.0 < fid(real, small)


def test_diversity_and_accuracy():
    two = np.array([[0.0, 0.0], [3.0, 4.0]])  # |difference| 5: half the random pairs differ
    assert diversity(two, pairs=4000, seed=1) == pytest.approx(2.5, abs=0.15)
    assert diversity(np.ones((50, 3)), pairs=10) == 0.0
    rng = np.random.default_rng(0)
    f = rng.normal(size=(500, 8))
    assert diversity(f, seed=3) == diversity(f, seed=3) != diversity(f, seed=4)
    assert diversity(f, pairs=300) == pytest.approx(4.0, rel=0.1)  # E|x - y| for N(0, 2 I_8) ~ 3.9
    with pytest.raises(ValueError, match="at least 2 samples"):
        diversity(f[:1])
    probs = np.array([[0.7, 0.3], [0.2, 0.8], [0.6, 0.4], [0.1, 0.9]])
    assert action_acc(probs, np.array([0, 1, 1, -1])) == pytest.approx(2 / 3)
    with pytest.raises(ValueError, match="disagree"):
        action_acc(probs, np.array([0, 1]))


def test_windows_are_canonical_and_resampled():
    J = _walk(T=121, fps=30.0) @ yaw_matrix(0.7).T.astype(np.float32) + np.float32([1.0, 2.0, 0.0])  # 4 s
    w, starts = motion_windows(J, 30.0, window=16, target_fps=10.0, stride=8)
    assert w.shape == (4, 16, 24, 3) and starts.tolist() == [0, 8, 16, 24]
    np.testing.assert_allclose(w[:, 0, 0, :2], 0.0, atol=1e-5)  # first pelvis at the origin
    np.testing.assert_allclose(heading(w[:, 0]), 0.0, atol=1e-5)  # facing +x
    np.testing.assert_allclose(w[:, 0, 0, 2], REST_JOINTS[0, 2], atol=1e-5)  # height kept
    # walking forwards at 1 m/s: 1.5 s later the pelvis is 1.5 m along +x
    np.testing.assert_allclose(w[:, -1, 0, :2], [[1.5, 0.0]] * 4, atol=1e-4)
    short, _ = motion_windows(J[:20], 30.0, window=16, target_fps=10.0)
    assert short.shape == (0, 16, 24, 3)
    acts = np.zeros((121, 3), np.float32)
    acts[:50, 0] = 1.0
    acts[40:, 1] = 1.5
    assert dominant_action(acts, 30.0, 16, 10.0, stride=8).tolist() == [0, 1, 1, 1]
    acts[:] = 0
    assert dominant_action(acts, 30.0, 16, 10.0, stride=8).tolist() == [-1] * 4


def test_encoder_is_invariant_to_world_placement_and_round_trips(tmp_path):
    enc = _tiny_encoder()
    J = _walk(T=60, fps=30.0)
    moved = J @ yaw_matrix(1.1).T + np.array([3.0, -2.0, 0.0])
    feats = enc.encode(np.stack([J, moved]), fps=30.0)
    assert feats.shape == (2, 4, 6)  # 20 frames at 10 fps, windows of 8 every 4
    np.testing.assert_allclose(feats[0], feats[1], atol=1e-5)
    probs = enc.classify(J, fps=30.0)
    assert probs.shape == (1, 4, 3)
    np.testing.assert_allclose(probs.sum(-1), 1.0, atol=1e-5)
    acts = np.zeros((60, 2), np.float32)
    acts[:, 1] = 1.0  # "walk" throughout; columns named in another order than the vocabulary
    labels = enc.window_labels(acts, ["sit", "walk"], fps=30.0)
    assert labels.tolist() == [[1, 1, 1, 1]]
    assert action_acc(probs, labels) == float((probs.argmax(-1) == 1).mean())
    with pytest.raises(ValueError, match="not in the vocabulary"):
        enc.window_labels(acts, ["sit", "fly"], fps=30.0)
    path = tmp_path / "enc.pt"
    enc.info = {"test_acc": 0.5}
    save_motion_encoder(enc, path, data={"name": "toy", "hash": "abc"})
    back = load_motion_encoder(path)
    assert back.vocabulary == ["stand", "walk", "sit"] and back.cfg == enc.cfg and back.info == {"test_acc": 0.5}
    np.testing.assert_array_equal(back.mean, enc.mean.astype(np.float32))
    np.testing.assert_array_equal(back.std, enc.std.astype(np.float32))
    np.testing.assert_allclose(back.encode(J, 30.0), feats[:1], atol=1e-6)
    with pytest.raises(ValueError, match="shorter than"):
        enc.encode(J[:10], 30.0)
    with pytest.raises(ValueError, match=r"\(N, T, 24, 3\)"):
        enc.encode(J[..., :2], 30.0)


def test_split_features_skip_clips_shorter_than_the_window():
    """A split with a 2 s and a 0.5 s clip (window 0.8 s): the short clip has no window and is
    skipped, the long one gives its windows; a split of short clips only is an error."""
    from types import SimpleNamespace

    from trumans.sequence import Sequence

    enc = _tiny_encoder()
    clips = {"long": Sequence(joints=_walk(T=60), fps=30.0), "short": Sequence(joints=_walk(T=15), fps=30.0)}
    splits = {"test": ["long", "short"], "val": ["short"]}
    data = SimpleNamespace(root="tiny", split=splits.__getitem__, load=clips.__getitem__)
    feats = split_features(enc, data, "test")
    np.testing.assert_allclose(feats, enc.encode(clips["long"].joints, 30.0)[0], atol=1e-6)
    with pytest.raises(ValueError, match="no clip of at least 0.8 s"):
        split_features(enc, data, "val")


def test_bad_checkpoints_are_refused(tmp_path):
    """Missing, junk, foreign, corrupted, wrong-kind and retired-format files: each a ValueError
    (FileNotFoundError) naming the problem and the fix; nothing is unpickled beyond plain data."""
    from trumans.model.checkpoint import save_checkpoint

    from helpers import tiny_checkpoint

    with pytest.raises(FileNotFoundError, match="trumans train --task motion_encoder"):
        load_motion_encoder(tmp_path / "none.pt")
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="not a readable trumans checkpoint"):
        load_motion_encoder(tmp_path / "junk.pt")
    torch.save({"weights": torch.zeros(3)}, tmp_path / "other.pt")
    with pytest.raises(ValueError, match="not a trumans checkpoint"):
        load_motion_encoder(tmp_path / "other.pt")
    save_checkpoint(tmp_path / "gen.pt", tiny_checkpoint())
    with pytest.raises(ValueError, match="is a 'generator' checkpoint, but a 'motion_encoder' checkpoint is needed"):
        load_motion_encoder(tmp_path / "gen.pt")
    enc = _tiny_encoder()
    good = tmp_path / "enc.pt"
    save_motion_encoder(enc, good)
    raw = torch.load(good, weights_only=True)
    raw["model"]["head.bias"] = raw["model"]["head.bias"] + 1.0  # altered weights, digest unchanged
    torch.save(raw, tmp_path / "altered.pt")
    with pytest.raises(ValueError, match="does not match the digest"):
        load_motion_encoder(tmp_path / "altered.pt")
    retired = {"format": "trumans-motion-encoder-1", "config": enc.cfg.to_dict(), "state_dict": enc.net.state_dict(),
               "mean": torch.from_numpy(enc.mean), "std": torch.from_numpy(enc.std), "vocabulary": enc.vocabulary}
    torch.save(retired, tmp_path / "retired.pt")
    with pytest.raises(ValueError, match=r"retired format .*scripts/ship_motion_encoder.py"):
        load_motion_encoder(tmp_path / "retired.pt")
    with pytest.raises(ValueError, match="unknown motion encoder config keys"):
        MotionEncoderConfig.from_dict({"num_actions": 2, "layers": 3})
    with pytest.raises(ValueError, match="window must be >= 4, got 2"):
        MotionEncoderConfig(num_actions=2, window=2)


def test_ship_script_converts_the_retired_format_without_changing_a_weight(tmp_path):
    """scripts/ship_motion_encoder.py on a retired-format file: the same tensors, vocabulary and
    config, the report as meta figures, identical features and probabilities."""
    import runpy
    import sys

    from helpers import REPO_ROOT

    enc = _tiny_encoder(3)
    enc.info = {"test_acc": 0.25, "fid_train_vs_test": 1.5}
    retired = {"format": "trumans-motion-encoder-1", "config": enc.cfg.to_dict(),
               "state_dict": {k: v.clone() for k, v in enc.net.state_dict().items()},
               "mean": torch.from_numpy(enc.mean), "std": torch.from_numpy(enc.std), "vocabulary": enc.vocabulary,
               "info": enc.info}
    torch.save(retired, tmp_path / "old.pt")
    argv = sys.argv
    try:
        sys.argv = ["ship_motion_encoder.py", str(tmp_path / "old.pt"), "--out", str(tmp_path / "new.pt")]
        with pytest.raises(SystemExit) as done:
            runpy.run_path(str(REPO_ROOT / "scripts" / "ship_motion_encoder.py"), run_name="__main__")
    finally:
        sys.argv = argv
    assert done.value.code == 0
    new = load_motion_encoder(tmp_path / "new.pt")
    assert new.cfg == enc.cfg and new.vocabulary == enc.vocabulary and new.info == enc.info
    for k, v in enc.net.state_dict().items():
        assert torch.equal(new.net.state_dict()[k], v)
    J = _walk(T=60)
    assert new.encode(J, 30.0).tobytes() == enc.encode(J, 30.0).tobytes()
    assert new.classify(J, 30.0).tobytes() == enc.classify(J, 30.0).tobytes()


def test_shipped_encoder_loads_and_recognises_actions():
    assert DEFAULT_MOTION_ENCODER.is_file(), "models/motion_encoder.pt is missing (trumans train --task motion_encoder)"
    assert DEFAULT_MOTION_ENCODER.stat().st_size < 3 * 2**20
    enc = load_motion_encoder()
    assert len(enc.vocabulary) == enc.cfg.num_actions and "walk" in enc.vocabulary
    assert enc.info["test_acc"] > 0.5
    # a clip it never saw: sit down on a chair, sit, stand up (30 fps toy case of an older motion
    # model). The shipped encoder has seen real sitting too and reads this clip's windows as
    # sitting: every window is sit_down / sit / stand_up, most are sit (the procedural-only encoder
    # shipped before it also placed the transitions at the ends; this one does not)
    seq, _ = make_case("sit", 0)
    names = [enc.vocabulary[i] for i in enc.classify(seq.joints, seq.fps, stride=8)[0].argmax(-1)]
    assert set(names) <= {"sit_down", "sit", "stand_up"} and names.count("sit") > len(names) / 2
    # real motion capture (CMU 131_01 at 120 fps, read through our BVH importer): walking
    walk = import_bvh(CMU_WALK_BVH, refine_steps=0)
    assert all(enc.vocabulary[i] == "walk" for i in enc.classify(walk.joints, walk.fps)[0].argmax(-1))


def test_eval_synthesis_refuses_a_motion_encoder_without_its_reference(tmp_path):
    """The shipped fid reference belongs to the shipped encoder: another encoder needs --data,
    and the command says so before sampling anything."""
    from trumans.cli import main

    with pytest.raises(ValueError, match="give --data DATASET"):
        main(["eval", "synthesis", "--motion-encoder", str(tmp_path / "enc.pt"), "--rooms", "1"])


def test_eval_synthesis_refuses_bad_sampler_settings():
    """Bad --eta / --steps are refused before any room is built, naming the values."""
    from trumans.cli import main

    with pytest.raises(ValueError, match=rf"--eta in \[0, 1\], got {SamplerConfig().steps}, 0, 1.5"):
        main(["eval", "synthesis", "--rooms", "1", "--eta", "1.5", "--naive-episodes", "0"])
    with pytest.raises(ValueError, match="--steps must be >= 1"):
        main(["eval", "synthesis", "--rooms", "1", "--steps", "0"])
    with pytest.raises(ValueError, match=r"--guidance scales must be finite and >= 0.*-1.0"):
        main(["eval", "synthesis", "--rooms", "1", "--guidance", "1", "-1"])
