"""Latent denoiser, noise schedulers (against closed forms) and the DDIM sampling loop."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from emogesture.diffusion import (
    DiffusionConfig, add_noise, ddim_sample, draw_noise, make_ddim_scheduler, make_ddpm_scheduler,
    make_generators, sample_timesteps, training_target,
)
from emogesture.errors import ConfigError
from emogesture.models.denoiser import DenoiserConfig, LatentDenoiser
from emogesture.models.generation import GenerationConfig
from emogesture.models.speech import AudioLatents


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture(scope="module")
def ddim():
    return make_ddim_scheduler(DiffusionConfig())


@pytest.fixture(scope="module")
def ddpm():
    return make_ddpm_scheduler(DiffusionConfig())


@pytest.fixture(scope="module")
def tiny() -> LatentDenoiser:
    torch.manual_seed(0)
    return LatentDenoiser(DenoiserConfig.preset("tiny")).eval()


def _conds(b: int, seed: int) -> AudioLatents:
    c, e, s = torch.randn(3, b, 256, generator=_gen(seed))
    return AudioLatents(c, e, s)


# --- schedulers --------------------------------------------------------------------------------------------


def test_config_is_explicit_and_validated(ddim, ddpm):
    assert ddim.config.clip_sample is False and ddim.config.set_alpha_to_one is False
    assert ddim.config.steps_offset == 1 and ddim.config.beta_schedule == "scaled_linear"
    assert ddpm.config.variance_type == "fixed_small" and ddpm.config.clip_sample is False
    assert ddpm.config.prediction_type == "epsilon" and ddpm.config.num_train_timesteps == 1000
    for bad in ({"beta_schedule": "cosine"}, {"beta_start": 0.02}):
        with pytest.raises(ConfigError):
            DiffusionConfig(**bad)
    with pytest.raises(ConfigError, match="num_inference_steps"):
        make_ddim_scheduler(DiffusionConfig(), 0)


def test_ddim_timesteps_leading_with_offset(ddim):
    assert ddim.timesteps.tolist() == [20 * i + 1 for i in reversed(range(50))]  # 981, 961, ..., 1
    s = make_ddim_scheduler(DiffusionConfig(), 25)
    assert s.timesteps.tolist() == [40 * i + 1 for i in reversed(range(25))]


def test_scaled_linear_betas_and_alphas_cumprod(ddim, ddpm):
    betas = np.linspace(0.00085**0.5, 0.012**0.5, 1000) ** 2
    for s in (ddim, ddpm):
        np.testing.assert_allclose(s.betas.double().numpy(), betas, rtol=1e-5)
        np.testing.assert_allclose(s.alphas_cumprod.double().numpy(), np.cumprod(1 - betas), rtol=1e-5)
    # set_alpha_to_one=False: the step after the last timestep goes to ᾱ_0, not to 1.
    assert float(ddim.final_alpha_cumprod) == pytest.approx(1 - betas[0], rel=1e-6)


def _ddim_closed_form(ac, x_t, eps, t, t_prev):
    a_t = ac[t]
    a_prev = ac[t_prev] if t_prev >= 0 else ac[0]
    x0 = (x_t - np.sqrt(1 - a_t) * eps) / np.sqrt(a_t)
    return np.sqrt(a_prev) * x0 + np.sqrt(1 - a_prev) * eps, x0


@pytest.mark.parametrize("t,t_prev", [(981, 961), (501, 481), (1, -19)])
def test_one_ddim_step_matches_closed_form(ddim, t, t_prev):
    x_t = torch.randn(3, 256, generator=_gen(1))
    eps = torch.randn(3, 256, generator=_gen(2))
    out = ddim.step(eps, torch.tensor(t), x_t, eta=0.0)
    ac = ddim.alphas_cumprod.double().numpy()
    want, x0 = _ddim_closed_form(ac, x_t.double().numpy(), eps.double().numpy(), t, t_prev)
    np.testing.assert_allclose(out.prev_sample.numpy(), want, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(out.pred_original_sample.numpy(), x0, rtol=1e-5, atol=1e-5)


def test_clip_sample_off_lets_large_x0_through():
    x_t = torch.full((1, 4), 50.0)
    eps = torch.zeros(1, 4)
    results = {}
    for clip in (False, True):
        s = make_ddim_scheduler(DiffusionConfig(clip_sample=clip))
        ac0 = float(s.alphas_cumprod[0])
        results[clip] = s.step(eps, torch.tensor(1), x_t, eta=0.0)
    x0 = 50.0 / np.sqrt(float(make_ddpm_scheduler().alphas_cumprod[1]))
    assert results[False].pred_original_sample[0, 0].item() == pytest.approx(x0, rel=1e-5)
    assert results[False].prev_sample[0, 0].item() == pytest.approx(np.sqrt(ac0) * x0, rel=1e-5)
    assert results[True].pred_original_sample.max().item() == 1.0
    assert results[True].prev_sample[0, 0].item() == pytest.approx(np.sqrt(ac0), rel=1e-5)


def test_add_noise_matches_forward_process(ddpm):
    z0 = torch.randn(4, 256, generator=_gen(3))
    noise = torch.randn(4, 256, generator=_gen(4))
    t = torch.tensor([0, 10, 500, 999])
    ac = ddpm.alphas_cumprod[t].double()[:, None]
    want = ac.sqrt() * z0.double() + (1 - ac).sqrt() * noise.double()
    torch.testing.assert_close(add_noise(ddpm, z0, noise, t).double(), want, rtol=1e-5, atol=1e-6)
    a = ddpm.alphas_cumprod[250].double()
    torch.testing.assert_close(add_noise(ddpm, z0, noise, 250).double(), a.sqrt() * z0.double() + (1 - a).sqrt() * noise.double(),
                               rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("kind", ["epsilon", "sample", "v_prediction"])
def test_training_target_by_prediction_type(kind):
    ddpm = make_ddpm_scheduler(DiffusionConfig(prediction_type=kind))
    z0, noise = torch.randn(2, 2, 256, generator=_gen(21))
    t = torch.tensor([5, 900])
    a = ddpm.alphas_cumprod[t][:, None]
    want = {"epsilon": noise, "sample": z0, "v_prediction": a.sqrt() * noise - (1 - a).sqrt() * z0}[kind]
    torch.testing.assert_close(training_target(ddpm, z0, noise, t), want, rtol=1e-5, atol=1e-6)
    # the same DDIM loop then turns a perfect prediction into the clean latent
    ddim = make_ddim_scheduler(DiffusionConfig(prediction_type=kind, set_alpha_to_one=True))
    x0 = torch.randn(2, 256, generator=_gen(22))

    def perfect(z_t, t, conditions):  # recovers the noise implied by z_t and x0, returns the target
        a = ddim.alphas_cumprod[t][:, None]
        eps = (z_t - a.sqrt() * x0) / (1 - a).sqrt()
        return training_target(ddim, x0, eps, t)

    torch.testing.assert_close(ddim_sample(perfect, ddim, (), _gen(23), batch_size=2), x0, rtol=1e-4, atol=1e-4)


def test_sample_timesteps_and_noise_are_per_sample():
    t = sample_timesteps(_gen(5), 1000, 1000)
    assert t.dtype == torch.int64 and 0 <= t.min() and t.max() <= 999 and len(t.unique()) > 500
    rows = draw_noise(make_generators([7, 8, 9]), 3, 16)
    torch.testing.assert_close(rows[1:2], draw_noise(make_generators([8]), 1, 16))
    with pytest.raises(ValueError):
        draw_noise(make_generators([1, 2]), 3, 16)


# --- denoiser ----------------------------------------------------------------------------------------------


def test_denoiser_presets_and_parameter_counts():
    paper = DenoiserConfig.preset("paper")
    assert (paper.width, paper.layers, paper.heads, paper.num_tokens) == (1024, 9, 4, 5)
    n = sum(p.numel() for p in LatentDenoiser(paper).parameters())
    t = sum(p.numel() for p in LatentDenoiser(DenoiserConfig.preset("tiny")).parameters())
    print(f"denoiser parameters: paper {n / 1e6:.2f} M, tiny {t / 1e6:.2f} M")
    assert 60e6 < n < 120e6 and t < 4e6


def test_denoiser_output_is_the_first_token(tiny):
    z = torch.randn(2, 256, generator=_gen(6))
    t = torch.tensor([3, 700])
    seen = {}
    h = tiny.transformer.register_forward_hook(lambda m, i, o: seen.setdefault("out", o))
    try:
        eps = tiny(z, t, _conds(2, 7))
    finally:
        h.remove()
    assert eps.shape == (2, 256) and seen["out"].shape == (2, 5, tiny.config.width)
    torch.testing.assert_close(eps, tiny.output(seen["out"][:, 0]))
    assert not torch.allclose(eps, tiny.output(seen["out"][:, 1]))


def test_denoiser_depends_on_t_and_every_condition(tiny):
    z = torch.randn(2, 256, generator=_gen(8))
    t = torch.tensor([100, 100])
    conds = list(_conds(2, 9))
    base = tiny(z, t, conds)
    assert (tiny(z, torch.tensor([101, 101]), conds) - base).abs().max() > 1e-4
    assert (tiny(z + 0.5, t, conds) - base).abs().max() > 1e-4
    for k in range(3):
        changed = list(conds)
        changed[k] = torch.randn(2, 256, generator=_gen(10 + k))
        assert (tiny(z, t, changed) - base).abs().max() > 1e-4, f"condition {k} is ignored"
    torch.testing.assert_close(tiny(z, torch.tensor(100), conds), base)  # a scalar t broadcasts
    with pytest.raises(ValueError):
        tiny(z, t, conds[:2])
    single = LatentDenoiser(DenoiserConfig.preset("tiny", num_conditions=1)).eval()
    assert single(z, t, (conds[0],)).shape == (2, 256)


def test_denoiser_is_batch_independent(tiny):
    z = torch.randn(3, 256, generator=_gen(13))
    t = torch.tensor([5, 400, 999])
    conds = _conds(3, 14)
    full = tiny(z, t, conds)
    one = tiny(z[1:2], t[1:2], [c[1:2] for c in conds])
    torch.testing.assert_close(full[1:2], one, rtol=1e-5, atol=1e-5)


# --- sampling loop -----------------------------------------------------------------------------------------


def test_ddim_sample_is_reproducible_and_batch_independent(tiny, ddim):
    conds = _conds(3, 15)
    a = ddim_sample(tiny, ddim, conds, make_generators([1, 2, 3]))
    b = ddim_sample(tiny, ddim, conds, make_generators([1, 2, 3]))
    torch.testing.assert_close(a, b, rtol=0, atol=0)
    alone = ddim_sample(tiny, ddim, [c[1:2] for c in conds], make_generators([2]))
    torch.testing.assert_close(a[1:2], alone, rtol=1e-5, atol=1e-5)
    other = ddim_sample(tiny, ddim, conds, make_generators([1, 20, 3]))
    assert (other[1] - a[1]).abs().max() > 1e-3
    torch.testing.assert_close(other[0], a[0], rtol=1e-5, atol=1e-5)
    z, traj = ddim_sample(tiny, ddim, conds, _gen(4), return_trajectory=True)
    assert traj.shape == (51, 3, 256) and torch.equal(traj[-1], z)
    torch.testing.assert_close(traj[0], torch.randn(3, 256, generator=_gen(4)))


def test_ddim_sample_with_eta_is_seeded_per_sample(tiny):
    s = make_ddim_scheduler(DiffusionConfig(), 10)
    conds = _conds(2, 16)
    a = ddim_sample(tiny, s, conds, make_generators([5, 6]), eta=1.0)
    alone = ddim_sample(tiny, s, [c[:1] for c in conds], make_generators([5]), eta=1.0)
    torch.testing.assert_close(a[:1], alone, rtol=1e-5, atol=1e-5)
    assert (a - ddim_sample(tiny, s, conds, make_generators([5, 6]), eta=0.0)).abs().max() > 1e-3


def _oracle(scheduler, x0):
    """A perfect ε-predictor for a known clean latent ``x0``."""

    def denoiser(z_t, t, conditions):
        a = scheduler.alphas_cumprod[t][:, None]
        return (z_t - a.sqrt() * x0) / (1 - a).sqrt()

    return denoiser


def test_ddim_loop_with_an_oracle_recovers_x0():
    x0 = torch.randn(2, 256, generator=_gen(17))
    # With set_alpha_to_one=True the final step lands exactly on x0.
    s1 = make_ddim_scheduler(DiffusionConfig(set_alpha_to_one=True))
    got = ddim_sample(_oracle(s1, x0), s1, (), _gen(18), batch_size=2)
    torch.testing.assert_close(got, x0, rtol=1e-4, atol=1e-4)
    # The paper's setting (set_alpha_to_one=False) stops at the noise level of t = 0: the oracle's ε stays the
    # initial ε_T, and the result is sqrt(ᾱ_0)·x0 + sqrt(1 - ᾱ_0)·ε_T, within ≈3 % noise of x0.
    s0 = make_ddim_scheduler(DiffusionConfig())
    got = ddim_sample(_oracle(s0, x0), s0, (), _gen(18), batch_size=2)
    noise = torch.randn(2, 256, generator=_gen(18))
    a_t, a_0 = s0.alphas_cumprod[981], s0.alphas_cumprod[0]
    eps_t = (noise - a_t.sqrt() * x0) / (1 - a_t).sqrt()
    torch.testing.assert_close(got, a_0.sqrt() * x0 + (1 - a_0).sqrt() * eps_t, rtol=1e-4, atol=1e-4)
    assert (got - x0).abs().max() < 0.2


# --- residual noise ----------------------------------------------------------------------------------------


def test_shrunk_covariance_is_ledoit_wolf_and_shrinks_toward_a_scaled_identity():
    from sklearn.covariance import ledoit_wolf

    from emogesture.diffusion.residual import residual_factor, shrunk_covariance

    rng = np.random.default_rng(0)
    for n, d in [(40, 6), (10, 32), (300, 3), (3, 2)]:
        x = rng.normal(size=(n, d)) @ rng.normal(size=(d, d)) + rng.normal(size=d)
        cov, delta = shrunk_covariance(x)
        want_cov, want_delta = ledoit_wolf(x)
        assert delta == pytest.approx(want_delta, abs=1e-12) and 0 <= delta <= 1
        np.testing.assert_allclose(cov, want_cov, rtol=1e-10, atol=1e-12)
        # a convex combination of the sample covariance and mu I: the trace (total variance) is kept,
        # off-diagonals scale by 1 - delta, and every eigenvalue moves toward mu along the same axes
        xc = x - x.mean(0)
        s = xc.T @ xc / n
        mu = np.trace(s) / d
        assert np.trace(cov) == pytest.approx(np.trace(s), rel=1e-12)
        off = ~np.eye(d, dtype=bool)
        np.testing.assert_allclose(cov[off], (1 - delta) * s[off], rtol=1e-10, atol=1e-12)
        before, after = np.linalg.eigvalsh(s), np.linalg.eigvalsh(cov)
        np.testing.assert_allclose(after, delta * mu + (1 - delta) * before, rtol=1e-9, atol=1e-12)
        # scale and shift: c x has c² the covariance and the same shrinkage; a constant offset changes nothing
        cov2, delta2 = shrunk_covariance(3.0 * x + 7.0)
        np.testing.assert_allclose(cov2, 9.0 * cov, rtol=1e-9)
        assert delta2 == pytest.approx(delta, abs=1e-9)
    # fewer samples than dimensions: the sample covariance is singular, the shrunk one positive definite
    few = rng.normal(size=(10, 32))
    cov, delta = shrunk_covariance(few)
    assert np.linalg.matrix_rank(np.cov(few.T, bias=True)) < 32 and delta > 0
    assert np.linalg.eigvalsh(cov).min() > 0
    L, _ = residual_factor(few)
    assert L.shape == (32, 32) and np.allclose(L, np.tril(L)) and np.all(np.diag(L) > 0)
    np.testing.assert_allclose(L.astype(np.float64) @ L.T, cov, rtol=1e-4, atol=1e-5)
    # isotropic data is shrunk a lot (the target is right), many samples of a correlated Gaussian little
    assert shrunk_covariance(rng.normal(size=(40, 16)))[1] > 0.5
    assert shrunk_covariance(rng.normal(size=(5000, 6)) @ rng.normal(size=(6, 6)))[1] < 0.05
    # one dimension: the variance itself; two samples: rounding never makes the weight negative
    one = rng.normal(size=(50, 1))
    assert shrunk_covariance(one)[0] == pytest.approx(np.array([[one.var()]]), rel=1e-12)
    assert all(shrunk_covariance(rng.normal(size=(2, k)))[1] >= 0 for k in range(2, 40))
    with pytest.raises(ValueError, match="residuals"):
        shrunk_covariance(np.zeros((1, 4)))


def test_residual_noise_is_seeded_per_sample_and_has_the_calibrated_covariance():
    from emogesture.diffusion.residual import add_residual_noise

    L = torch.tensor([[1.0, 0.0], [0.5, 0.2]])
    z = torch.zeros(2, 2)
    a = add_residual_noise(z, L, make_generators([3, 4]))
    alone = add_residual_noise(z[:1], L, make_generators([3]))
    torch.testing.assert_close(a[:1], alone)
    assert add_residual_noise(z, L, make_generators([3, 4]), scale=0.0) is z
    many = add_residual_noise(torch.zeros(20000, 2), L, _gen(0), scale=2.0)
    torch.testing.assert_close(torch.cov(many.T), 4 * L @ L.T, atol=0.08, rtol=0.05)
    with pytest.raises(ValueError, match="residual factor"):
        add_residual_noise(z, torch.eye(3), _gen(0))
    with pytest.raises(ConfigError, match="residual_scale"):
        GenerationConfig(residual_scale=-1.0)


# --- our DDIM steps against diffusers' ----------------------------------------------------------------------


@pytest.mark.parametrize("settings", [
    {},
    {"prediction_type": "sample"},
    {"prediction_type": "v_prediction", "set_alpha_to_one": True, "timestep_spacing": "trailing"},
    {"beta_schedule": "linear", "timestep_spacing": "linspace", "num_inference_steps": 7, "clip_sample": True},
    {"beta_schedule": "squaredcos_cap_v2", "steps_offset": 0, "num_inference_steps": 13},
])
@pytest.mark.parametrize("eta", [0.0, 0.7])
def test_ddim_sampler_matches_diffusers(settings, eta):
    settings = dict(settings)
    steps = settings.pop("num_inference_steps", 50)
    cfg = DiffusionConfig(**settings)
    ours, theirs = make_ddim_scheduler(cfg, steps), make_ddim_scheduler(cfg, steps, backend="diffusers")
    assert ours.timesteps.tolist() == theirs.timesteps.tolist()
    torch.testing.assert_close(ours.alphas_cumprod, theirs.alphas_cumprod)
    assert float(ours.final_alpha_cumprod) == pytest.approx(float(theirs.final_alpha_cumprod))
    w = torch.randn(16, 16, generator=_gen(31)) / 4

    def denoiser(z_t, t, conditions):  # any fixed function of (z_t, t)
        return torch.tanh(z_t @ w) + t[:, None].float() / 1000

    a = ddim_sample(denoiser, ours, (), make_generators([1, 2]), batch_size=2, latent_dim=16, eta=eta)
    b = ddim_sample(denoiser, theirs, (), make_generators([1, 2]), batch_size=2, latent_dim=16, eta=eta)
    torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)
    if settings.get("prediction_type") == "v_prediction":
        z0, noise, t = torch.randn(2, 16), torch.randn(2, 16), torch.tensor([3, 700])
        torch.testing.assert_close(ours.get_velocity(z0, noise, t), theirs.get_velocity(z0, noise, t))
