"""The filter's linear skip for joints (trumans.refine.wiener): neighbourhoods, the closed-form fit on
known cases, translation equivariance, checkpoint round trip and errors."""
import numpy as np
import pytest
import torch

from trumans.refine.filter import FilterModel, configure_skip, filter_denoiser_config, FilterNetConfig
from trumans.refine.frame import FRAME_DIM, JOINTS
from trumans.refine.wiener import JointWiener, fit_joint_wiener, neighbourhoods
from trumans.model.checkpoint import Checkpoint
from trumans.model.diffusion import DiffusionConfig
from trumans.model.episodes import Normalizer
from trumans.model.nets.denoiser import Denoiser


def _walks(n=60, L=24, seed=0):
    """(n, L, 72) smooth random trajectories: a random pose moving along a line, each coordinate
    with its own slow sine."""
    rng = np.random.default_rng(seed)
    pose = rng.normal(0, 0.3, (n, 1, 24, 3))
    vel = rng.normal(0, 0.02, (n, 1, 1, 3))
    t = np.arange(L)[None, :, None, None]
    wobble = 0.05 * np.sin(rng.uniform(0.05, 0.2, (n, 1, 24, 3)) * t + rng.uniform(0, 6.3, (n, 1, 24, 3)))
    return (pose + vel * t + wobble).reshape(n, L, 72)


def test_neighbourhoods_values_and_edges():
    X = torch.arange(2 * 5 * 72, dtype=torch.float64).reshape(2, 5, 72)
    u, P = neighbourhoods(X, 1)
    assert u.shape == (2, 5, 3 * 72) and P.shape == (2, 5, 72)
    # frame 2's neighbourhood is frames 1, 2, 3 minus frame 2's pelvis; frame 0 repeats itself on the left
    want = torch.cat([X[0, k] - X[0, 2, :3].repeat(24) for k in (1, 2, 3)])
    torch.testing.assert_close(u[0, 2], want)
    torch.testing.assert_close(u[0, 0, :72], u[0, 0, 72:144])
    torch.testing.assert_close(P[1, 4], X[1, 4, :3].repeat(24))
    with pytest.raises(ValueError, match="joints must be"):
        neighbourhoods(torch.zeros(2, 5, 71), 1)


def test_fit_recovers_identity_without_noise_and_averages_noise():
    clean = _walks()
    w = fit_joint_wiener(clean, clean, radius=2, ridge=1e-8)
    out = w(torch.from_numpy(clean).float()).numpy()
    np.testing.assert_allclose(out[:, 2:-2], clean[:, 2:-2], atol=5e-4)  # fitted on full neighbourhoods
    # white noise on a (nearly) linear motion: the estimate beats the input by about sqrt(5)
    rng = np.random.default_rng(1)
    clean = _walks(n=600)
    noisy = clean + rng.normal(0, 0.01, clean.shape)
    w = fit_joint_wiener(noisy, clean, radius=2)
    test = _walks(seed=2)
    tn = test + rng.normal(0, 0.01, test.shape)
    est = w(torch.from_numpy(tn).float()).numpy()
    inner = slice(2, -2)
    err_in = np.abs(tn - test)[:, inner].mean()
    err_out = np.abs(est - test)[:, inner].mean()
    assert err_out < 0.6 * err_in
    # translation equivariance: moving the whole input moves the estimate the same way
    shift = torch.tensor([0.5, -1.0, 0.2]).repeat(24).float()
    x = torch.from_numpy(tn).float()
    torch.testing.assert_close(w(x + shift), w(x) + shift, atol=1e-5, rtol=0)


def test_fit_errors():
    a = _walks(n=4, L=6)
    with pytest.raises(ValueError, match="full"):
        fit_joint_wiener(a, a, radius=3)
    b = a.copy(); b[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="fill the tracked gaps"):
        fit_joint_wiener(b, a, radius=1)
    with pytest.raises(ValueError, match="both be"):
        fit_joint_wiener(a, a[:, :5], radius=1)


def test_extra_round_trip_errors_and_model_skip():
    w = fit_joint_wiener(_walks(n=8, L=12), _walks(n=8, L=12), radius=1)
    back = JointWiener.from_extra(w.to_extra())
    torch.testing.assert_close(back.weight, w.weight)
    bad = w.to_extra(); bad["weight"] = bad["weight"][:10]
    with pytest.raises(ValueError, match="inconsistent"):
        JointWiener.from_extra(bad)
    bad = w.to_extra(); bad["bias"] = bad["bias"] * np.nan
    with pytest.raises(ValueError, match="not finite"):
        JointWiener.from_extra(bad)
    # in the model: the joints' skip is the Wiener estimate in normalised units, other features the low-pass
    net = FilterNetConfig(d_model=16, layers=1, heads=2, ff=16, window=12, overlap=2, wiener_radius=1)
    mc = filter_denoiser_config(net, 1)
    den = Denoiser(mc)
    rng = np.random.default_rng(0)
    norm = Normalizer(rng.normal(0, 0.1, FRAME_DIM), rng.uniform(0.5, 2, FRAME_DIM))
    ck = Checkpoint(kind="filter", model_config=mc, model_state=den.state_dict(), diffusion_config=DiffusionConfig(),
                    normalizer=norm, extra={"categories": ["box"], "skip_sigma": 0.0, "wiener": w.to_extra()})
    model = configure_skip(FilterModel(den), ck)
    cond = torch.from_numpy(rng.normal(0, 1, (2, 12, 261)).astype(np.float32))
    skip = model.skip(cond)
    m, s = torch.tensor(norm.mean[JOINTS]).float(), torch.tensor(norm.std[JOINTS]).float()
    torch.testing.assert_close(skip[..., JOINTS] * s + m, w(cond[..., JOINTS] * s + m), atol=1e-4, rtol=1e-4)
    torch.testing.assert_close(skip[..., 72:], cond[..., 72:225])  # sigma 0: the rest passes through
    with pytest.raises(ValueError, match="needs the filter's normalizer"):
        FilterModel(den).set_wiener(w)
