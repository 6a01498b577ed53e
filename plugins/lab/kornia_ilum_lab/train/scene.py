r"""The scene branch's recipe: ``kornia-ilum train --estimator scene`` trains
:class:`~kornia_ilum.estimators.scene.SceneStrength`, the light's strength from the whole photo.

Each training portrait comes with its whole rendered frame (``PortraitConfig.frame``, at
:data:`~kornia_ilum.estimators.scene.SCENE_SIZE` pixels) and the face's box in it; the network reads the frame
(letterboxed, :func:`~kornia_ilum.estimators.scene.scene_input`), the face blanked and the exposure metered on the
rest, and is trained by the negative log-likelihood of the true log energy per channel under a
Laplace distribution of its predicted spread,

.. math::

    \frac{1}{3} \sum_c \frac{|\log E_c - \hat e_c|}{b} + \log b,

so that the spread is the network's own honest doubt: wide where the frame shows nothing the light falls on
besides the face (a plain backdrop), narrow where a wall, a floor or clothes tell the light's strength apart from
the skin's. The face network is not part of it: its estimate and the scene's are fused at inference by their
spreads (:func:`~kornia_ilum.estimators.scene.fuse_strength`), so each is trained on its own. What the frame
shows is the data's choice: ``--data surroundings=P`` (walls and floors), and caches rendered with clothes and
wider views (``kornia-ilum synth subjects --clothes --face-fraction F``, docs/lightstage.rst).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import safetensors.torch
import torch
from torch import nn

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.core.files import atomic_write, sha256_file
from kornia_ilum.estimators.scene import SCENE_SIZE, SceneStrength, scene_input
from kornia_ilum.metrics import total_radiance
from kornia_ilum_lab.synth.lightstage.portraits import PortraitDataset
from kornia_ilum_lab.train.config import RuntimeSettings, TrainConfig
from kornia_ilum_lab.train.recipes import Recipe

__all__ = ["SceneRecipe", "scene_batch", "scene_nll", "tone_slope"]


def scene_batch(batch: dict[str, Any], device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
    r"""``(frames, log_energy)`` of a collated batch with frames: the network's input and the true log energy per
    channel.

    Each frame is cut to its ``frame_window`` where the batch has them (a common photo's aspect around the face,
    :func:`~kornia_ilum_lab.synth.lightstage.portraits.aspect_windows`), so the network learns on photos
    letterboxed as :func:`~kornia_ilum.estimators.scene.scene_input` letterboxes a 4:3 or 16:9 photo.

    Shape:
        - Output: :math:`(B, 5, S, S)`, :math:`(B, 3)`
    """
    frames = batch["frame"].to(device).float() / 255.0
    boxes = batch["frame_box"].to(device).float()
    size = frames.shape[-1]
    if "frame_window" in batch:
        first = torch.zeros(1, dtype=torch.int64, device=device)
        parts = []
        for i, (x0, y0, x1, y1) in enumerate(batch["frame_window"].round().long().tolist()):
            shift = torch.tensor([x0, y0, x0, y0], dtype=boxes.dtype, device=device)
            window = frames[i : i + 1, :, y0:y1, x0:x1]
            parts.append(scene_input(window, boxes[i : i + 1] - shift, first, size=size))
        x = torch.cat(parts)
    else:
        x = scene_input(frames, boxes, torch.arange(len(frames), device=device), size=size)
    truth = torch.log(total_radiance(batch["mirror_ball"].to(device).float()).clamp(min=1e-12))
    return x, truth


def scene_nll(log_energy: torch.Tensor, spread: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    r"""The Laplace negative log-likelihood of the module docstring, averaged over the batch.

    Examples:
        >>> round(scene_nll(torch.zeros(1, 3), torch.ones(1), torch.ones(1, 3)).item(), 4)  # |1 - 0| / 1 + log 1
        1.0
    """
    return ((truth - log_energy).abs().mean(1) / spread + torch.log(spread)).mean()


def tone_slope(error: torch.Tensor, tones: torch.Tensor) -> torch.Tensor:
    r"""How far the log-energy error moves per standard deviation of the skin's Monk tone, over a batch: the
    covariance of ``error`` :math:`(B,)` with ``tones`` :math:`(B,)` over the tones' standard deviation (samples of
    unknown tone, ``<= 0``, left out; 0 with fewer than two known tones). 0 for a branch blind to the skin.

    Examples:
        >>> tones = torch.tensor([1.0, 3.0, 5.0, 7.0])
        >>> round(tone_slope(-0.1 * tones, tones).item(), 4)  # 0.1 lower per tone, the tones' sd sqrt(5)
        -0.2236
    """
    known = tones > 0
    if int(known.sum()) < 2:
        return error.new_zeros(())
    t, e = tones[known].to(error), error[known]
    t = t - t.mean()
    return (t * (e - e.mean())).mean() / t.pow(2).mean().sqrt().clamp(min=1e-6)


class SceneRecipe(Recipe):
    """``scene``: :class:`~kornia_ilum.estimators.scene.SceneStrength` on whole frames (module docstring).

    Its one option, ``--model tone_blind=L``, adds ``L`` times the square of :func:`tone_slope` of the batch's
    errors to the loss: the NLL alone lets the branch read whatever skin the frame shows besides the face (a neck,
    arms) as a reference, as the face network does, which gives the same fall of the strength with the tone;
    the term asks for errors that do not follow the tone, which is what makes the branch's estimate worth fusing
    with the face's. No adversarial term and none of ``ours``' terms; its spread is its own NLL's, so the
    export's calibrations (``--fit-spread``, ``--calibrate-energy``) do not apply. Its weights are written in
    float32 (0.8 MB).

    Examples:
        >>> recipe = SceneRecipe()
        >>> model, disc = recipe.build()
        >>> type(model).__name__, disc, recipe.estimator(model) is model
        ('SceneStrength', None, True)
    """

    name = "scene"
    log_fields = ("spread", "tone")
    tone_blind = 0.0

    def build(self, **options: Any) -> tuple[nn.Module, None]:
        self.tone_blind = float(options.pop("tone_blind", 0.0))
        if options or not self.tone_blind >= 0.0:
            raise ValueCheckError(f"the scene branch's one model option is tone_blind >= 0, got "
                                  f"{sorted(options) or self.tone_blind}")
        return SceneStrength(), None

    def dataset(self, dataset: PortraitDataset) -> PortraitDataset:
        """The portraits with their whole frames at :data:`~kornia_ilum.estimators.scene.SCENE_SIZE`."""
        config = dataclasses.replace(dataset.config, frame=SCENE_SIZE)
        return type(dataset)(dataset.fields, config, seed=dataset.seed)

    def calibration_dataset(self, dataset: PortraitDataset) -> PortraitDataset:
        raise ValueCheckError("the scene branch's spread is its own NLL's: train it without --fit-spread, "
                              "--calibrate-energy and --calibrate-colour")

    def estimator(self, model: nn.Module) -> nn.Module:
        return model

    def step(self, *, model: nn.Module, disc: nn.Module | None, opt_g: torch.optim.Optimizer,
             opt_d: torch.optim.Optimizer | None, batch: dict[str, Any], device: torch.device,
             config: TrainConfig, runtime: RuntimeSettings) -> dict[str, torch.Tensor]:
        """One step of :func:`scene_nll`; ``rec`` is the mean absolute error of the log energy (natural log)."""
        x, truth = scene_batch(batch, device)
        log_energy, spread = model(x)
        slope = tone_slope((log_energy - truth).mean(1), batch["skin_tone"].to(device))
        loss = scene_nll(log_energy, spread, truth) + self.tone_blind * slope**2
        opt_g.zero_grad(set_to_none=True)
        loss.backward()
        opt_g.step()
        zero = torch.zeros(())
        return {"loss": loss.detach(), "rec": (truth - log_energy).abs().mean().detach(), "adv": zero,
                "disc": zero, "extra": zero, "spread": spread.mean().detach(), "tone": slope.detach()}

    def export(self, estimator: nn.Module, path: Path, probe: dict[str, Any]) -> dict[str, Any]:
        """float32 weights, and the mean absolute log-energy error and mean spread on the probe."""
        tensors = {k: v.detach().float().contiguous() for k, v in estimator.state_dict().items()}
        atomic_write(path, lambda tmp: safetensors.torch.save_file(tensors, str(tmp)))
        with torch.no_grad():
            x, truth = scene_batch(probe, torch.device("cpu"))
            log_energy, spread = estimator(x)
        return {"file": path.name, "sha256": sha256_file(path), "dtype": "float32",
                "log_energy_error_probe": float((truth - log_energy).abs().mean()),
                "spread_probe": float(spread.mean())}
