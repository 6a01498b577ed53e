"""kornia_ilum_lab.train.losses: the multi-scale rendering loss and the discriminator's images."""

from __future__ import annotations

import math

import torch

from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.render import mirror_ball_pyramid, sphere_pyramid
from kornia_ilum_lab.train import BRDF_WEIGHTS, SCALES, training_losses
from kornia_ilum.metrics import reconstruction_loss
from kornia_ilum_lab.train.losses import (
    albedo_loss,
    discriminator_images,
    energy_loss,
    energy_nll,
    log_energy,
    to_true_energy,
)


class TestLosses:
    def test_zero_at_the_truth_and_sensitive_at_every_scale(self) -> None:
        valid = mirror_ball_valid(32)
        truth = (torch.rand(2, 3, 32, 32) + 0.1) * valid
        pred = mirror_ball_pyramid(truth, SCALES)
        loss, parts = training_losses(pred, truth, brdf_weights=BRDF_WEIGHTS)
        assert loss.item() < 1e-6 and set(parts) == {f"rec_{b}" for b in BRDF_WEIGHTS}
        for s in SCALES:  # one bright pixel in the lighting of one scale: the loss sees it
            bumped = {k: v.clone() for k, v in pred.items()}
            i = s // 2
            bumped[s][:, :, i, i] += 50.0
            assert training_losses(bumped, truth, brdf_weights=BRDF_WEIGHTS)[0].item() > 1e-3, s

    def test_gradients_are_finite_on_black(self) -> None:
        pred = {s: torch.zeros(1, 3, s, s, requires_grad=True) for s in SCALES}
        loss, _ = training_losses(pred, torch.zeros(1, 3, 32, 32), brdf_weights=BRDF_WEIGHTS)
        loss.backward()
        assert all(torch.isfinite(pred[s].grad).all() for s in SCALES)

    def test_given_truth_is_the_pyramid_of_the_target(self) -> None:
        """Passing the target's pyramid (as train_step does) gives the loss of computing it, bit for bit."""
        valid = mirror_ball_valid(32)
        gen = torch.Generator().manual_seed(0)
        target = torch.rand(2, 3, 32, 32, generator=gen) * valid
        pred = {s: torch.rand(2, 3, s, s, generator=gen) * mirror_ball_valid(s) for s in SCALES}
        plain, parts = training_losses(pred, target, brdf_weights=BRDF_WEIGHTS, lambda_scale=0.5)
        truth = mirror_ball_pyramid(target, SCALES)
        given, given_parts = training_losses(
            pred, target, brdf_weights=BRDF_WEIGHTS, lambda_scale=0.5, truth=truth
        )
        assert torch.equal(plain, given) and all(torch.equal(parts[k], given_parts[k]) for k in parts)

    def test_brdf_weights_are_the_papers(self) -> None:
        assert BRDF_WEIGHTS == {"diffuse": 0.6, "matte_silver": 0.2, "mirror": 0.2}
        assert math.isclose(sum(BRDF_WEIGHTS.values()), 1.0)


class TestDiscriminatorImages:
    def test_the_mirror_sphere_of_each_scale(self) -> None:
        lighting = mirror_ball_pyramid(torch.rand(2, 3, 32, 32) * 3 * mirror_ball_valid(32), SCALES)
        images = discriminator_images(lighting)
        assert sorted(images) == list(SCALES)
        for s in SCALES:
            want = sphere_pyramid(lighting[s], sizes=(s,), brdfs=("mirror",), gamma="safe")[f"mirror_{s}"]
            assert images[s].shape == (2, 3, s, s) and torch.equal(images[s], want)
            assert images[s].min() >= 0 and images[s].max() <= 1  # clipped and gamma-encoded


class TestEnergyLoss:
    def test_is_the_log_ratio_of_each_channels_energy(self) -> None:
        truth = torch.rand(2, 3, 32, 32) * mirror_ball_valid(32)
        scale = torch.tensor([2.0, 0.5, 1.0]).view(1, 3, 1, 1)
        expected = torch.tensor([2.0, 0.5, 1.0]).log().abs().mean()
        torch.testing.assert_close(energy_loss(truth * scale, truth), expected, atol=1e-5, rtol=0)
        assert energy_loss(truth, truth).item() == 0.0

    def test_symmetric_in_log_unlike_the_rendering_loss(self) -> None:
        truth = torch.rand(4, 3, 32, 32) * mirror_ball_valid(32)
        torch.testing.assert_close(energy_loss(2 * truth, truth), energy_loss(truth / 2, truth))

    def test_weighs_by_solid_angle_and_ignores_outside_the_ball(self) -> None:
        a = torch.ones(1, 3, 32, 32) * mirror_ball_valid(32)
        b = a + 100.0 * (1 - mirror_ball_valid(32).float())  # only the corners differ
        assert energy_loss(b, a).item() < 1e-6

    def test_finite_for_black_lightings_and_gradient(self) -> None:
        pred = torch.zeros(1, 3, 32, 32, requires_grad=True)
        loss = energy_loss(pred, torch.zeros(1, 3, 32, 32))
        loss.backward()
        assert loss.item() == 0.0 and torch.isfinite(pred.grad).all()

    def test_negative_radiance_counts_as_zero(self) -> None:
        """An unclamped SH reconstruction (sh's training path) can sum to a negative energy: no NaN."""
        truth = torch.ones(1, 3, 32, 32) * mirror_ball_valid(32)
        pred = (truth * torch.linspace(-1, 0.5, 32)).requires_grad_()  # mostly negative, total below 0
        loss = energy_loss(pred, truth)
        loss.backward()
        assert torch.isfinite(loss) and torch.isfinite(pred.grad).all()
        torch.testing.assert_close(loss, energy_loss(pred.detach().clamp(min=0), truth))
        assert (pred.grad[pred.detach() > 0] != 0).any() and (pred.grad[pred.detach() < 0] == 0).all()


class TestTheScaleApart:
    def test_to_true_energy_keeps_the_shape_and_takes_the_truths_energy(self) -> None:
        valid = mirror_ball_valid(32)
        gen = torch.Generator().manual_seed(0)
        truth = (torch.rand(2, 3, 32, 32, generator=gen) + 0.1) * valid
        pred = (torch.rand(2, 3, 32, 32, generator=gen) + 0.1) * valid
        a, b = to_true_energy({32: pred}, {32: truth})[32], to_true_energy({32: 7.0 * pred}, {32: truth})[32]
        torch.testing.assert_close(a, b)
        torch.testing.assert_close(log_energy(a, eps=0.0), log_energy(truth, eps=0.0))
        x = pred.clone().requires_grad_()  # L_rec of the result has no gradient along the prediction's scale
        reconstruction_loss(to_true_energy({32: x}, {32: truth})[32], truth, brdf="diffuse").mean().backward()
        torch.testing.assert_close((x.grad * pred).sum(), torch.tensor(0.0), atol=1e-6, rtol=0)

    def test_the_likelihood_is_least_at_the_truth_with_the_mean_error_as_spread(self) -> None:
        truth = torch.ones(64, 3, 8, 8)
        error = torch.linspace(-1.0, 1.0, 64)
        pred = truth * error.exp()[:, None, None, None]
        mean_abs = error.abs().mean()
        best = energy_nll(pred, truth, torch.full((64,), float(mean_abs.log())))
        for b in (0.5 * mean_abs, 2 * mean_abs):
            assert energy_nll(pred, truth, torch.full((64,), float(b.log()))) > best
        biased = energy_nll(pred * 1.5, truth, torch.full((64,), float(mean_abs.log())))
        assert biased > best

    def test_albedo_loss_leaves_unknown_tones_out(self) -> None:
        pred = torch.tensor([-1.0, -3.0, 5.0])
        full = albedo_loss(pred, torch.tensor([1, 10, -1]))
        assert torch.isclose(full, albedo_loss(pred[:2], torch.tensor([1, 10])))
