"""The HOI filter end to end: filter-mode denoiser, training task, inference over windows with
resampling and blending, the refine CLI, checkpoint round trip and clear errors."""
from dataclasses import replace

import numpy as np
import pytest
import torch

from trumans.refine.evaluate import clip_figures, tune_savgol
from trumans.refine.pipeline import HOIFilter, RefineOptions
from trumans.refine.post_steps import PostStepsConfig
from trumans.refine import FRAME_DIM, add_clean_imu, frames_from_sequence
from trumans.refine.data import FilterWindows, window_objects
from trumans.refine.filter import FilterModel, FilterNetConfig, category_indices, filter_denoiser_config
from trumans.refine.frame import IMU_FLAG, JOINTS, OBJ_T, ROTATIONS
from trumans.model.checkpoint import Checkpoint, save_checkpoint
from trumans.model.diffusion import DiffusionConfig
from trumans.model.episodes import Normalizer
from trumans.model.nets.denoiser import Denoiser
from trumans.sequence import ObjectTrack, Sequence, load_sequence, save_sequence

from helpers import carried_box_clip

NET = FilterNetConfig(d_model=32, layers=1, heads=2, ff=32, window=16, overlap=4, fps=30.0, wiener_radius=2)
CATS = ["box", "cup"]
DIFF = DiffusionConfig(steps=50, loss="l1", prediction="x0")


def _ckpt(path, zero=True, seed=0):
    """A tiny filter checkpoint; zero=True zeroes the output layer and the skip's smoothing, so
    x̂0 = the tracked input."""
    torch.manual_seed(seed)
    mc = filter_denoiser_config(NET, len(CATS))
    net = Denoiser(mc)
    if zero:
        torch.nn.init.zeros_(net.out_proj.weight)
        torch.nn.init.zeros_(net.out_proj.bias)
    rng = np.random.default_rng(0)
    norm = Normalizer(rng.normal(0, 0.1, FRAME_DIM), rng.uniform(0.5, 2, FRAME_DIM))
    ck = Checkpoint(kind="filter", model_config=mc, diffusion_config=DIFF, model_state=FilterModel(net).state_dict(),
                    normalizer=norm, fps=NET.fps, extra={"categories": CATS, "window": NET.window, "overlap": NET.overlap, "skip_sigma": 0.0 if zero else 2.0},
                    meta={"net": NET.to_dict()})
    save_checkpoint(path, ck)
    return path


def test_filter_mode_denoiser_errors():
    m = Denoiser(filter_denoiser_config(NET, 2))
    x, t, c = torch.zeros(3, 16, FRAME_DIM), torch.zeros(3, dtype=torch.long), torch.zeros(3, 16, 261)
    assert m(x, t, frame_cond=c, category=torch.tensor([0, 1, 1])).shape == (3, 16, FRAME_DIM)
    with pytest.raises(ValueError, match=r"category indices must be in \[0, 2\)"):
        m(x, t, frame_cond=c, category=torch.tensor([0, 2, 1]))
    with pytest.raises(ValueError, match="category must be"):
        m(x, t, frame_cond=c)
    with pytest.raises(ValueError, match="frame_cond must be"):
        m(x, t, frame_cond=c[:, :8], category=torch.tensor([0, 1, 1]))
    with pytest.raises(ValueError, match="'chair' is unknown to this filter"):
        category_indices(["box", "chair"], CATS)
    # the category changes the output
    m.eval()
    a = m(x, t, frame_cond=c, category=torch.tensor([0, 0, 0]))
    b = m(x, t, frame_cond=c, category=torch.tensor([1, 1, 1]))
    assert not torch.allclose(a, b)


def _tracked(T=100, seed=0):
    s = carried_box_clip(T=T, seed=seed)
    f, _ = frames_from_sequence(s, "box_0")
    return s, f


def test_identity_filter_reproduces_input_across_windows(tmp_path):
    """With a zero correction network every window returns its tracked input; the windows in their
    own canonical frames, the blend and the resampling must give the input back exactly."""
    filt = HOIFilter.load(_ckpt(tmp_path / "f.pt"))
    s, f = _tracked(T=100)
    # the clip stands 4 cm off the floor (the floor step would move it) and the bones step would give
    # the gaps' interpolated frames back their bone lengths
    keep = PostStepsConfig().switched(floor=False, bones=False)
    for opts in (RefineOptions(num_steps=3, post=keep), RefineOptions(mode="sdedit", strength=0.3, post=keep)):
        out = filt.refine_frames(f, 30.0, "box", opts)
        assert out.shape == f.shape and np.isfinite(out).all()
        np.testing.assert_allclose(out[:, :OBJ_T.stop], f[:, :OBJ_T.stop], atol=2e-4)
    # a short clip (one padded window) and another frame rate (resampled to 30 fps and back)
    opts = RefineOptions(post=keep)
    np.testing.assert_allclose(filt.refine_frames(f[:10], 30.0, "box", opts)[:, JOINTS], f[:10, JOINTS], atol=2e-4)
    out60 = filt.refine_frames(f[::1], 60.0, "box", opts)
    np.testing.assert_allclose(out60[:, JOINTS], f[:, JOINTS], atol=2e-3)
    # NaN frames and joints: the output is complete, the gaps linearly interpolated (identity filter,
    # the residual's spline for short clean gaps off)
    g = f.copy()
    g[20:30, :OBJ_T.stop] = np.nan
    g[50, :3] = np.nan
    linear = RefineOptions(post=replace(keep, residual=replace(keep.residual, spline_gaps=False)))
    out = filt.refine_frames(g, 30.0, "box", linear)
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out[60:, JOINTS], f[60:, JOINTS], atol=2e-4)
    lin = f[19, JOINTS] + (np.arange(1, 11) / 11)[:, None] * (f[30, JOINTS] - f[19, JOINTS])
    np.testing.assert_allclose(out[20:30, JOINTS], lin, atol=2e-4)
    np.testing.assert_allclose(out[50, :3], (f[49, :3] + f[51, :3]) / 2, atol=2e-4)
    splined = filt.refine_frames(g, 30.0, "box", opts)  # by default: the spline through the tracked frames
    np.testing.assert_allclose(splined[60:, JOINTS], f[60:, JOINTS], atol=2e-4)
    err = lambda o: np.abs(o[20:30, JOINTS] - f[20:30, JOINTS]).mean()
    assert err(splined) < 0.5 * err(out), (err(splined), err(out))
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        filt.refine_frames(f[:, :200], 30.0, "box")
    with pytest.raises(ValueError, match="'lamp' is unknown"):
        filt.refine_frames(f, 30.0, "lamp")


def test_refine_sequence_and_cli(tmp_path, capsys):
    import json

    from trumans.cli import console_main

    ck = _ckpt(tmp_path / "f.pt", zero=False)
    s, _ = _tracked(T=70)
    s.joints[10:14] = np.nan
    s.allow_missing = True
    save_sequence(s, tmp_path / "tracked.npz")
    rc = console_main(["refine", str(tmp_path / "tracked.npz"), "--out", str(tmp_path / "r.npz"),
                       "--checkpoint", str(ck), "--steps", "2", "--json"])
    assert rc == 0
    r = load_sequence(tmp_path / "r.npz")
    assert r.num_frames == 70 and r.fps == 30.0 and np.isfinite(r.joints).all() and r.rotations is not None
    assert set(r.objects) == {"box_0", "lamp"}
    printed = capsys.readouterr().out
    assert '"object": "box_0"' in printed
    assert json.loads(printed.strip().splitlines()[-1])["post_steps"] == ["residual", "body_drift", "foot_lock", "rest_pooling",
                                                                            "hand_link", "gate", "smoother", "bones", "floor"]
    # same seed, same output
    filt = HOIFilter.load(ck)
    a, _ = filt.refine_sequence(s, options=RefineOptions(num_steps=2, eta=1.0, seed=3))
    b, _ = filt.refine_sequence(s, options=RefineOptions(num_steps=2, eta=1.0, seed=3))
    np.testing.assert_array_equal(a.joints, b.joints)
    # rest pooling touches the object only
    rc = console_main(["refine", str(tmp_path / "tracked.npz"), "--out", str(tmp_path / "np.npz"),
                       "--checkpoint", str(ck), "--steps", "2", "--no-rest-pooling"])
    assert rc == 0
    r2 = load_sequence(tmp_path / "np.npz")
    np.testing.assert_allclose(r2.joints, r.joints, atol=1e-6)
    # the body-drift correction moves the joints only, by one translation per frame
    rc = console_main(["refine", str(tmp_path / "tracked.npz"), "--out", str(tmp_path / "nd.npz"),
                       "--checkpoint", str(ck), "--steps", "2", "--no-drift-correction"])
    assert rc == 0
    r3 = load_sequence(tmp_path / "nd.npz")
    shift = r.joints - r3.joints
    np.testing.assert_allclose(shift, shift[:, :1].repeat(shift.shape[1], 1), atol=1e-5)
    np.testing.assert_allclose(r3.rotations, r.rotations, atol=1e-6)
    np.testing.assert_allclose(r3.objects["box_0"].pose, r.objects["box_0"].pose, atol=1e-6)
    # the hinge fit: a box is not hinged, so the default is --no-hinge; --hinge turns the object only
    for flag, name in (("--hinge", "h.npz"), ("--no-hinge", "nh.npz")):
        assert console_main(["refine", str(tmp_path / "tracked.npz"), "--out", str(tmp_path / name),
                             "--checkpoint", str(ck), "--steps", "2", flag]) == 0
    r4, r5 = load_sequence(tmp_path / "h.npz"), load_sequence(tmp_path / "nh.npz")
    np.testing.assert_array_equal(r5.objects["box_0"].pose, r.objects["box_0"].pose)
    np.testing.assert_allclose(r4.joints, r.joints, atol=1e-6)
    assert np.abs(r4.objects["box_0"].pose[:, :3, 3] - r.objects["box_0"].pose[:, :3, 3]).max() > 1e-3
    assert console_main(["refine", str(tmp_path / "tracked.npz"), "--out", str(tmp_path / "x.npz"),
                         "--hinge", "--no-hinge"]) == 2 and not (tmp_path / "x.npz").exists()
    capsys.readouterr()
    rc = console_main(["refine", str(tmp_path / "tracked.npz"), "--out", str(tmp_path / "x.npz"),
                       "--checkpoint", str(ck), "--category", "chair"])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("trumans: error:") and "'chair' is unknown" in err
    rc = console_main(["refine", str(tmp_path / "missing.npz"), "--out", str(tmp_path / "x.npz"), "--checkpoint", str(ck)])
    assert rc == 2 and "does not exist" in capsys.readouterr().err
    # --interactions (the older spelling of `trumans track`) goes to the tracker, which refuses a track with
    # missing frames: the tracker's own error, the same as `trumans track` gives
    rc = console_main(["refine", str(tmp_path / "tracked.npz"), "--out", str(tmp_path / "x.npz"), "--interactions"])
    err_old = capsys.readouterr().err
    rc_new = console_main(["track", str(tmp_path / "tracked.npz"), "--out", str(tmp_path / "x.npz")])
    err_new = capsys.readouterr().err
    assert rc == rc_new == 2 and err_old == err_new and "joints contain NaN" in err_new
    assert not (tmp_path / "x.npz").exists()


def _dataset(root):
    """A tiny dataset folder of exact clips (one per split) for the filter task."""
    from trumans.dataset import content_hash, write_index
    from trumans.skeleton import rest_offsets

    splits = {}
    for k, split in enumerate(("train", "val", "test")):
        s = carried_box_clip(T=80, seed=k)
        s.extra["offsets"] = rest_offsets().astype(np.float32)
        rel = f"sequences/{split}.npz"
        save_sequence(s, root / rel)
        splits[split] = [rel]
    files = [p for v in splits.values() for p in v]
    write_index(root, {"name": "tiny-hoi", "version": 1, "fps": 30.0, "vocabulary": [], "splits": splits,
                       "scenes": {}, "hash": content_hash(root, files)})
    return root


def test_filter_task_trains_through_the_loop(tmp_path):
    from trumans.train.tasks.filter import FilterTask, phase_weights
    from trumans.train.loop import train
    from trumans.train.tasks import make_task

    data = _dataset(tmp_path / "data")
    task = make_task("filter", overrides={"net": NET.to_dict(), "diffusion": DIFF.to_dict(),
                                          "train": {"batch_size": 2, "checkpoint_every": 10, "val_every": 10},
                                          "filter": {"val_windows": 2, "val_sampling_steps": 2, "stride": 8,
                                                     "wiener_windows": 8, "wiener_real_windows": 8}})
    assert isinstance(task, FilterTask)
    res = train(task, data, tmp_path / "run", steps=3, progress=False)
    assert res.steps == 3 and np.isfinite(res.val_loss) and res.val_loss_zero_baseline > 0
    filt = HOIFilter.load(tmp_path / "run" / "checkpoint.pt")
    assert filt.categories == ["box"] and filt.window == 16
    assert filt.model.wiener is not None and filt.model.wiener.radius == 2  # fitted in setup, shipped in extra
    torch.testing.assert_close(filt.model.wiener.weight, task.wiener.weight)
    assert make_task("filter", ablate=["wiener"]).config.net.wiener_radius == 0
    # fine-tuning from the run (--init), on one category: starts from its EMA weights and its skip
    ft = make_task("filter", overrides={"net": NET.to_dict(), "diffusion": DIFF.to_dict(),
                                        "train": {"batch_size": 2, "checkpoint_every": 10, "val_every": 10},
                                        "filter": {"val_windows": 2, "val_sampling_steps": 2, "stride": 8,
                                                   "wiener_windows": 8, "wiener_real_windows": 8,
                                                   "categories": ["box"], "w_residual": 1.0}})
    res0 = train(ft, data, tmp_path / "ft0", steps=0, progress=False, init=tmp_path / "run" / "checkpoint.pt")
    f0 = HOIFilter.load(res0.checkpoint)
    for k, v in filt.model.state_dict().items():
        torch.testing.assert_close(f0.model.state_dict()[k], v)
    torch.testing.assert_close(f0.model.wiener.weight, filt.model.wiener.weight)
    assert f0.ckpt.meta["init"] == str(tmp_path / "run" / "checkpoint.pt")
    assert train(ft, data, tmp_path / "ft2", steps=2, progress=False, init=tmp_path / "run" / "checkpoint.pt").steps == 2
    ft_loss = ft.loss(ft.build_model(), ft.batch(0, 0, 1), torch.Generator().manual_seed(0), "cpu")
    assert "residual" in ft_loss.terms and torch.isfinite(ft_loss.terms["residual"])  # the residual step in the loop
    with pytest.raises(ValueError, match="not in this data's vocabulary"):
        ft.train_data.only(["chair"])
    from trumans.train.tasks.filter import real_motion_windows
    real = real_motion_windows(16, 30.0, stride=200)  # the corpus's train split, joints only
    assert real.shape[1:] == (16, FRAME_DIM) and np.isfinite(real[..., JOINTS]).all() and np.isnan(real[..., OBJ_T]).all()
    b = task.batch(0, 0, 1)
    assert b.x0.shape == (2, 16, FRAME_DIM) and b.cond.shape == (2, 16, 261) and torch.isfinite(b.cond).all()
    loss = task.loss(task.build_model(), b, torch.Generator().manual_seed(0), "cpu")
    assert set(loss.terms) == {"simple", "off", "vel", "consist", "imu", "pose"}
    assert all(torch.isfinite(v) for v in loss.terms.values())
    w0, w1, w2 = (phase_weights(task.config.filter, k) for k in (0.0, 0.4, 0.9))
    assert sum(w0.values()) == w0["pose"] > 0 and w1["off"] > 0 and w1["imu"] == 0 and w2["imu"] > 0
    abl = make_task("filter", ablate=["regularisers"])
    assert abl.config.filter.w_off == 0 and abl.config.filter.w_imu == 0 and abl.config.filter.w_residual == 0
    with pytest.raises(ValueError, match="unknown ablation 'scene'"):
        make_task("filter", ablate=["scene"])
    with pytest.raises(ValueError, match="unknown key"):
        make_task("filter", overrides={"filter": {"stepz": 3}})


def test_window_objects_and_eval_figures():
    s = carried_box_clip(T=64)
    assert window_objects(s, np.array([0, 32]), 32) == ["box_0", "box_0"]  # the lamp never moves
    _, f = _tracked(T=64)
    f = add_clean_imu(f[None], 30.0)[0]
    fig = clip_figures(f, f, f[:, :72], f, 30.0)
    assert fig["mpjpe_in_mm"] == 0 and fig["mpjpe_out_mm"] == 0 and fig["obj_rot_err_out_deg"] < 1e-3
    assert fig["accel_err_out"] == 0 and fig["accel_gt"] > 0 and fig["hand_obj_dist_cm"] == 0
    rng = np.random.default_rng(0)
    noisy = f.copy()
    noisy[:, :72] += rng.normal(0, 0.02, (64, 72))
    assert tune_savgol([(noisy, f)], windows=(5, 9, 15)) in (5, 9, 15)


def test_filter_checkpoint_kind_and_errors(tmp_path):
    from trumans.model.checkpoint import load_checkpoint

    p = _ckpt(tmp_path / "f.pt")
    ck = load_checkpoint(p, kind="filter")
    assert ck.extra["categories"] == CATS and isinstance(ck.build_model(), FilterModel)
    with pytest.raises(ValueError, match="'filter' checkpoint, but a 'generator'"):
        load_checkpoint(p)
    ck.extra = {"categories": ["box"]}  # 2 embeddings, 1 name
    save_checkpoint(tmp_path / "bad.pt", ck)
    with pytest.raises(ValueError, match="embeds 2 categories"):
        HOIFilter.load(tmp_path / "bad.pt")
    with pytest.raises(FileNotFoundError):
        HOIFilter.load(tmp_path / "none.pt")


def test_eval_refine_command(tmp_path, capsys):
    import json

    from trumans.cli import console_main

    data = _dataset(tmp_path / "data")
    ck = _ckpt(tmp_path / "f.pt", zero=False)
    rc = console_main(["eval", "refine", str(ck), "--data", str(data), "--clip", "32", "--steps", "2", "--json"])
    out = capsys.readouterr().out
    assert rc == 0
    res = json.loads(out.strip().splitlines()[-1])
    for k in ("mpjpe_in_mm", "mpjpe_out_mm", "mpjpe_savgol_mm", "accel_err_in", "accel_err_out", "accel_gt",
              "obj_t_err_in_cm", "obj_t_err_out_cm", "obj_rot_err_in_deg", "obj_rot_err_out_deg",
              "hand_obj_dist_cm", "frames_per_s", "frames_per_s_per_clip", "mpjpe_in_ra_mm", "mpjpe_out_ra_mm",
              "mpjpe_savgol_ra_mm", "obj_t_err_out_no_rest_cm", "obj_rot_err_out_no_rest_deg", "mpjpe_out_no_drift_mm",
              "mpjpe_out_drift_oracle_mm"):
        assert np.isfinite(res[k]), k
    assert res["rest_pooling"] is True and res["hand_link"] is True and res["hinge"] is True and "obj_t_err_out_no_rest_cm" not in res["no_imu"]
    assert "mpjpe_out_drift_oracle_mm" not in res["no_imu"]
    assert res["no_imu"]["imu_clips"] == 0 and res["drift"]["imu_clips"] == res["drift"]["clips"] > 0
    assert res["savgol_window"] % 2 == 1
    rc = console_main(["eval", "refine", str(ck), "--data", str(data), "--clip", "8"])
    assert rc == 2 and "--clip must be >=" in capsys.readouterr().err


def test_smooth_time():
    from trumans.refine.filter import smooth_time

    t = torch.arange(40, dtype=torch.float64)
    lin = torch.stack([t, 2 * t + 1], -1)[None]  # (1, 40, 2)
    np.testing.assert_allclose(smooth_time(lin, 2.0)[0, 8:-8], lin[0, 8:-8], atol=1e-9)  # interior: linear kept
    assert torch.equal(smooth_time(lin, 0.0), lin)
    noise = torch.randn(1, 400, 3, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    assert smooth_time(noise, 2.0).std() < 0.5 * noise.std()


def test_refine_many_equals_one_by_one(tmp_path):
    """All windows of several sequences (different lengths, rates, categories) in one batch give what
    each sequence gives alone (a random network: the equality is not that of an identity), also when
    the batch is split into chunks."""
    filt = HOIFilter.load(_ckpt(tmp_path / "f.pt", zero=False))
    seqs = [_tracked(T=T, seed=i)[1] for i, T in enumerate((100, 10, 150))]
    fps, cats = [30.0, 30.0, 60.0], ["box", "box", filt.categories[-1]]
    opts = RefineOptions(num_steps=2, post=PostStepsConfig().switched(gate=False))  # the gate would keep the clean input
    alone = [filt.refine_frames(f, r, c, opts) for f, r, c in zip(seqs, fps, cats)]
    for batch in (256, 3):
        together = filt.refine_many(seqs, fps, cats, replace(opts, batch=batch))
        for a, b, f in zip(alone, together, seqs):
            assert b.shape == f.shape
            np.testing.assert_allclose(b, a, atol=1e-4)
    assert not np.allclose(alone[0][:, JOINTS], seqs[0][:, JOINTS], atol=1e-3)  # the network does change it
    assert filt.refine_many([], [], []) == []
    with pytest.raises(ValueError, match="one fps and category per sequence"):
        filt.refine_many(seqs, fps[:2], cats)
    with pytest.raises(ValueError, match="fps must be a positive number"):
        filt.refine_many(seqs[:1], [0.0], cats[:1])


def test_root_aligned_mpjpe_ignores_a_body_translation_and_real_clips_are_body_only():
    from trumans.refine.evaluate import real_clips, root_aligned_errors

    rng = np.random.default_rng(0)
    Jc = rng.normal(size=(20, 24, 3))
    drift = np.cumsum(rng.normal(0, 0.01, (20, 1, 3)), axis=0)  # a whole-body translation per frame
    np.testing.assert_allclose(root_aligned_errors(Jc + drift, Jc), 0.0, atol=1e-12)
    J = Jc.copy()
    J[:, 5] += [0.0, 0.03, 0.04]  # one joint 5 cm off, the root exact
    e = root_aligned_errors(J, Jc)
    np.testing.assert_allclose(e[:, 5], 0.05)
    assert np.allclose(np.delete(e, 5, axis=1), 0.0)
    clips = real_clips(64, 3, seed=0)
    assert clips.shape == (3, 64, 235) and np.isfinite(clips[..., JOINTS]).all()
    assert np.isnan(clips[..., 72:216]).all() and (clips[..., OBJ_T] == 0).all()  # no rotations, a still placeholder
    assert (clips[..., 234] == 0).all()  # no IMU


def test_the_real_motion_block_runs_end_to_end(tmp_path):
    """``eval refine --real``'s block refines corrupted corpus clips (body only) through the whole
    pipeline: the figures come back finite, the output moved off the corrupted input."""
    from trumans.refine.evaluate import evaluate_real

    filt = HOIFilter.load(_ckpt(tmp_path / "f.pt", zero=False))
    res = evaluate_real(filt, 64, 2, savgol_window=9, seed=0, options=RefineOptions(num_steps=1))
    assert set(res) == {"default", "drift"}
    for block in res.values():
        assert block["clips"] == 2 and all(np.isfinite(block[k]) for k in ("mpjpe_in_mm", "mpjpe_out_mm", "accel_err_out"))
        assert block["mpjpe_out_mm"] != block["mpjpe_in_mm"]


def test_flips_are_turned_back_before_resampling(tmp_path):
    """Flips are turned back at the input's rate: resampling 45 -> 30 fps never blends a flipped frame
    with an unflipped one (halfway between R and R S_z the 6D average has no first column, so its
    orthonormalisation is arbitrary)."""
    from trumans.refine.frame import OBJ_R
    from trumans.rotations import matrix_to_6d, sixd_to_matrix

    filt = HOIFilter.load(_ckpt(tmp_path / "f.pt"))
    frames, _ = frames_from_sequence(carried_box_clip(T=120))
    flipped = frames.copy()
    S = np.diag([-1.0, -1.0, 1.0])  # pi about the object's own z
    flipped[23:78, OBJ_R] = matrix_to_6d(sixd_to_matrix(frames[23:78, OBJ_R].astype(np.float64)) @ S)  # ends between output frames
    want = filt._windows(frames, 45.0, RefineOptions())["tracked"][:, OBJ_R].astype(np.float64)
    got = filt._windows(flipped, 45.0, RefineOptions())["tracked"][:, OBJ_R].astype(np.float64)
    np.testing.assert_allclose(sixd_to_matrix(got), sixd_to_matrix(want), atol=1e-4)


def test_foot_skate_counts_slides_over_the_truths_planted_runs():
    from trumans.eval.metrics import foot_skate_planted_cm
    from trumans.skeleton import FOOT_JOINTS

    T = 20
    Jc = np.zeros((T, 24, 3))
    Jc[:, :, 2] = 0.5
    Jc[:, FOOT_JOINTS, 2] = 0.05  # four foot joints standing still: one planted run each
    J = Jc.copy()
    J[:, FOOT_JOINTS[0], 0] += 0.01 * np.arange(T)  # the output's left ankle slides 1 cm per frame
    assert foot_skate_planted_cm(Jc, Jc, 30.0) == 0.0
    assert abs(foot_skate_planted_cm(J, Jc, 30.0) - 100 * 0.19 / 4) < 1e-9  # 19 cm on one run of four
    moving = Jc.copy()
    moving[:, :, 0] += 0.02 * np.arange(T)[:, None]  # 0.6 m/s: the truth never plants a foot
    assert np.isnan(foot_skate_planted_cm(J, moving, 30.0))


def test_post_steps_follow_the_options_and_the_category():
    from dataclasses import replace

    from trumans.refine.post_steps import PostStepsConfig

    d = PostStepsConfig()
    hinge_any = replace(d, hinge=replace(d.hinge, any_category=True))
    guards = ["gate", "smoother", "bones", "floor"]
    first = ["residual", "body_drift", "foot_lock"]
    assert RefineOptions().post_steps("door") == first + ["rest_pooling", "hand_link", "hinge"] + guards
    assert RefineOptions().post_steps("cup") == first + ["rest_pooling", "hand_link"] + guards
    assert "hinge" in RefineOptions(post=hinge_any).post_steps("cup")
    assert RefineOptions(post=replace(d.switched(hinge=False), rest_pooling=replace(d.rest_pooling, hand_link=False))
                         ).post_steps("door") == first + ["rest_pooling"] + guards
    assert RefineOptions(post=hinge_any.switched(rest_pooling=False)).post_steps("door") == first + guards  # the hinge needs pooled rests
    assert RefineOptions(post=d.switched(residual=False, body_drift=False, foot_lock=False, rest_pooling=False, gate=False,
                                         smoother=False, bones=False, floor=False)).post_steps("door") == []


def test_a_track_never_observed_is_refused_not_invented(tmp_path):
    filt = HOIFilter.load(_ckpt(tmp_path / "f.pt"))
    with pytest.raises(ValueError, match="body is missing \\(NaN\\) on every frame"):
        filt.refine_frames(np.full((40, FRAME_DIM), np.nan, np.float32), 30.0, "box")
    _, f = _tracked(T=40)
    f[:, 216:225] = np.nan  # the object is never seen
    with pytest.raises(ValueError, match="object's pose is missing \\(NaN\\) on every frame"):
        filt.refine_frames(f, 30.0, "box")


def test_window_motion_types_and_the_balanced_batch(tmp_path):
    """Windows know their body motion types from the joints; balance_types draws that share of a
    batch type by type (only windows of a present type), and 0 leaves the uniform draw unchanged."""
    from helpers import sit_stand_take
    from trumans.refine.data import window_motion_types
    from trumans.train.tasks import make_task

    J = sit_stand_take().astype(np.float64)  # stand 1.5 s, sit down, sit 3 s, stand up, stand
    human = np.concatenate([J.reshape(len(J), -1), np.zeros((len(J), ROTATIONS.stop - 72))], -1).astype(np.float32)
    starts = np.arange(0, len(J) - 32 + 1, 16)
    fw = FilterWindows(human=[human], objects=[np.zeros((len(J), 19), np.float32)], offsets=np.zeros((1, 24, 3)),
                       windows=np.stack([np.zeros_like(starts), starts, np.zeros_like(starts)], -1),
                       categories=np.zeros(len(starts), np.int64), category_names=["box"], files=["x"], window=32,
                       fps=30.0)
    types = window_motion_types(fw, min_frames=8)
    assert types.shape == (len(starts), 4) and not types[:, 0].any() and not types[:, 2:].any()  # no walk, lie, get-up
    sits = types[:, 1]
    assert not sits[0] and sits[len(starts) // 2] and not sits[-1]  # standing at both ends, seated in the middle
    assert not window_motion_types(fw, min_frames=33).any()  # more frames than a window holds

    data = _dataset(tmp_path / "data")
    over = {"net": NET.to_dict(), "diffusion": DIFF.to_dict(), "train": {"batch_size": 8},
            "filter": {"val_windows": 2, "val_sampling_steps": 2, "stride": 4, "wiener_windows": 8,
                       "wiener_real_windows": 8}}
    plain = make_task("filter", overrides=over)
    plain.setup(data, tmp_path / "a", is_main=True, barrier=lambda: None, prev=None, progress=False)
    zero = make_task("filter", overrides={**over, "filter": {**over["filter"], "balance_types": 0.0}})
    zero.setup(data, tmp_path / "b", is_main=True, barrier=lambda: None, prev=None, progress=False)
    torch.testing.assert_close(plain.batch(3, 0, 1).x0, zero.batch(3, 0, 1).x0)  # 0 = the uniform draw
    full = make_task("filter", overrides={**over, "filter": {**over["filter"], "balance_types": 1.0}})
    full.setup(data, tmp_path / "c", is_main=True, barrier=lambda: None, prev=None, progress=False)
    present = window_motion_types(full.train_data).any(0)
    assert present.any()
    for step in range(3):
        b = full.batch(step, 0, 1)
        assert b.x0.shape == (8, 16, FRAME_DIM) and torch.isfinite(b.x0).all()
    with pytest.raises(ValueError, match="balance_types is a share"):
        make_task("filter", overrides={**over, "filter": {**over["filter"], "balance_types": 1.5}})
