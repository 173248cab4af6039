"""``smokyslam train-upsampler``: pix2pix training of the up-sampler on simulated worlds.

The table of contents of :meth:`UpsamplerTrainer.train`: build (or load from the cache) the
training and validation pairs, restore the checkpoint when resuming, then per epoch: a fixed
number of steps on random crops (rotated and flipped), a validation error index on the whole
validation maps, a checkpoint. At the end the last epoch's averaged generator is calibrated
(the logit offset that validates best, searched around ``-log(occupied_weight)``) and written
with its training record, beside the config, the history and a loss plot.

Losses (pix2pix, with milliMap's map prior), on the dense value ``v`` (1 occupied, 0 free,
0.5 unknown) against the observed truth ``y``, weighted per cell (true walls
``occupied_weight``, cells no lidar saw ``unknown_weight``, free 1):

- L1, as pix2pix, and binary cross-entropy on the logits. L1 alone stalls here: walls are a
  few percent of the cells, the sigmoid saturates at "free" within a hundred steps and its
  gradient with it (measured: F1 0 after 400 steps; with cross-entropy 0.65 after 600);
- the line prior: L1 between the responses of four fixed line detectors on ``v`` and ``y``;
- adversarial: a PatchGAN judges (sparse input, map) pairs; non-saturating logistic loss.

Validation and the written weights use an exponential moving average of the generator's
weights (``ema_decay``): a GAN's generator oscillates from step to step (measured: the
validation error index of the raw generator swung between 0.048 and 0.106 over epochs 3-6),
the average does not. Inference adds ``-log(occupied_weight)`` to the logits (``weights.py``).

The weights written are the last epoch's average, not the best-validating epoch's: over six
validation worlds the error index can dip for an epoch or a few (0.065 -> 0.050 -> 0.062 at
epoch 12 of one run, 0.053 -> 0.045-0.046 over epochs 22-25 of another), and the networks of
those dips found fewer corridor walls on unseen worlds (mean occupied F1 of 38 unseen maps 0.79
against 0.81-0.82 for the last epochs of the same runs).
The per-epoch validation stays in the history, to watch.

Training is deterministic for a seed on CPU (fixed thread count, deterministic algorithms,
every random draw from seeded generators, restored exactly on resume). Ctrl-C leaves the last
checkpoint intact (checkpoints are written whole, then renamed).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smokyslam.config import SmokySlamConfig, write_config
from smokyslam.errors import ConfigError, TrainingInterruptedError
from smokyslam.upsample.checkpoint import read_checkpoint, write_checkpoint
from smokyslam.upsample.crops import CropSampler
from smokyslam.upsample.dataset import MapPair, build_pairs, training_seeds
from smokyslam.upsample.training_outputs import (
    artefact_paths,
    plot_history,
    write_history,
)
from smokyslam.upsample.validation import calibrate, validation_logits, validation_scores

logger = logging.getLogger(__name__)

ProgressCallback = Callable[[float, float, str], None]
"""(steps done, steps in all, status text)."""


@dataclass
class TrainingResult:
    weights_path: Path
    history: list[dict[str, float]]
    wall_s: float
    calibrated: dict[str, float]
    """Validation scores of the written weights (last epoch, calibrated offset)."""


class UpsamplerTrainer:
    """Trains one generator; state lives here between epochs."""

    def __init__(
        self,
        config: SmokySlamConfig,
        out: Path,
        seed: int,
        device: str,
        command: str,
        data_dir: Path | None = None,
    ) -> None:
        import torch

        from smokyslam.upsample.model import PatchDiscriminator, UNetGenerator, line_kernels

        if device == "cuda" and not torch.cuda.is_available():
            raise ConfigError("--device cuda: no CUDA device here (use --device cpu)")
        if device not in ("cpu", "cuda"):
            raise ConfigError(f"--device must be cpu or cuda, got '{device}'")
        self.config, self.training = config, config.upsample.training
        self.out, self.paths, self.seed, self.command = out, artefact_paths(out), seed, command
        if data_dir is not None:
            self.paths["data"] = data_dir
        self.device = torch.device(device)
        torch.set_num_threads(self.training.threads)
        torch.use_deterministic_algorithms(True)
        torch.manual_seed(seed)
        model = self.training.model
        self.generator = UNetGenerator(model.base_channels, model.depth, model.max_channels)
        self.average = UNetGenerator(model.base_channels, model.depth, model.max_channels)
        self.average.load_state_dict(self.generator.state_dict())
        self.average.requires_grad_(False)
        self.discriminator = PatchDiscriminator()
        self.generator.to(self.device)
        self.average.to(self.device)
        self.discriminator.to(self.device)
        rate, betas = self.training.learning_rate, (0.5, 0.999)
        self.opt_g = torch.optim.Adam(self.generator.parameters(), rate, betas=betas)
        self.opt_d = torch.optim.Adam(self.discriminator.parameters(), rate, betas=betas)
        self.schedules = [
            torch.optim.lr_scheduler.LambdaLR(opt, self._rate_factor)
            for opt in (self.opt_g, self.opt_d)
        ]
        self.kernels = line_kernels().to(self.device)
        self.rng = np.random.default_rng([seed, 29])
        self.epoch, self.history = 0, []
        self.wall_s = 0.0

    def _rate_factor(self, epoch: int) -> float:
        """pix2pix's schedule: full rate, then a linear decay (here to a tenth)."""
        t = self.training
        decaying = max(t.epochs - t.decay_from_epoch, 1)
        done = min(max(epoch - t.decay_from_epoch, 0) / decaying, 1.0)
        return 1.0 - 0.9 * done

    # -- the table of contents ---------------------------------------------------------------

    def train(self, resume: bool, on_progress: ProgressCallback | None = None) -> TrainingResult:
        if resume:  # before the pairs: a bad checkpoint fails in seconds, not after simulation
            self._restore()
        train_seeds, val_seeds = training_seeds(self.training)
        pairs = build_pairs(train_seeds, self.config, self.paths["data"], self.training.jobs)
        validation = build_pairs(val_seeds, self.config, self.paths["data"], self.training.jobs)
        sampler = CropSampler(pairs, self.training, self.rng)
        total = self.training.epochs * self.training.steps_per_epoch
        try:
            while self.epoch < self.training.epochs:
                started = time.perf_counter()
                losses = self._epoch(sampler, on_progress, total)
                scores = self._validate(validation)
                self.epoch += 1
                for schedule in self.schedules:
                    schedule.step()
                self.wall_s += time.perf_counter() - started
                self.history.append({"epoch": self.epoch, **losses, **scores})
                write_checkpoint(self.paths["checkpoint"], self._state())
                logger.info("epoch %d: %s", self.epoch, self.history[-1])
        except KeyboardInterrupt:
            raise TrainingInterruptedError(self.paths["checkpoint"], self.epoch) from None
        return self._finish(validation)

    # -- steps ---------------------------------------------------------------------------------

    def _epoch(self, sampler: CropSampler, on_progress, total: int) -> dict[str, float]:
        import torch

        self.generator.train()
        sums: dict[str, float] = {}
        steps = self.training.steps_per_epoch
        for step in range(steps):
            inputs, targets, weights = (
                torch.from_numpy(a).to(self.device) for a in sampler.batch(self.training.batch)
            )
            for key, value in self._step(inputs, targets, weights).items():
                sums[key] = sums.get(key, 0.0) + value
            if on_progress:
                done = self.epoch * steps + step + 1
                on_progress(done, total, self._status())
        return {key: value / steps for key, value in sums.items()}

    def _step(self, inputs, targets, weights) -> dict[str, float]:
        import torch
        from torch.nn import functional

        from smokyslam.upsample.model import line_responses

        t = self.training
        logits = self.generator(inputs)
        value = torch.sigmoid(logits)
        real = self.discriminator(inputs, targets)
        fake = self.discriminator(inputs, value.detach())
        loss_d = 0.5 * (functional.softplus(-real).mean() + functional.softplus(fake).mean())
        self.opt_d.zero_grad(set_to_none=True)
        loss_d.backward()
        self.opt_d.step()

        l1 = (weights * (value - targets).abs()).sum() / weights.sum()
        bce = functional.binary_cross_entropy_with_logits(logits, targets, reduction="none")
        bce = (weights * bce).sum() / weights.sum()
        lines = (line_responses(value, self.kernels) - line_responses(targets, self.kernels)).abs()
        line = lines.mean()
        adversarial = functional.softplus(-self.discriminator(inputs, value)).mean()
        loss_g = (
            t.bce_weight * bce
            + t.l1_weight * l1
            + t.line_weight * line
            + t.adversarial_weight * adversarial
        )
        self.opt_g.zero_grad(set_to_none=True)
        loss_g.backward()
        self.opt_g.step()
        with torch.no_grad():
            for mean, current in zip(
                self.average.parameters(), self.generator.parameters(), strict=True
            ):
                mean.lerp_(current, 1.0 - t.ema_decay)
            return {
                "loss_g": float(loss_g),
                "loss_d": float(loss_d),
                "l1": float(l1),
                "bce": float(bce),
                "line": float(line),
                "adversarial": float(adversarial),
            }

    def _validate(self, pairs: list[MapPair]) -> dict[str, float]:
        from smokyslam.upsample.weights import logit_offset

        offset = logit_offset(self.training.occupied_weight)
        return validation_scores(pairs, self._logits(pairs), offset)

    def _logits(self, pairs: list[MapPair]) -> list[np.ndarray]:
        self.average.eval()
        upsample = self.config.upsample
        logits = validation_logits(
            self.average.cpu(), self.training.model, pairs, upsample.margin_cells,
            upsample.max_pass_cells,
        )  # fmt: skip
        self.average.to(self.device)
        return logits

    def _status(self) -> str:
        if not self.history:
            return f"epoch {self.epoch + 1}"
        last = self.history[-1]
        return f"epoch {self.epoch + 1}, val EI {last['val_error_index']:.3f}"

    # -- state ---------------------------------------------------------------------------------

    def _state(self) -> dict[str, Any]:
        import torch

        return {
            "training": self.training.model_dump(mode="json"),
            "seed": self.seed,
            "epoch": self.epoch,
            "history": self.history,
            "wall_s": self.wall_s,
            "generator": self.generator.state_dict(),
            "average": self.average.state_dict(),
            "discriminator": self.discriminator.state_dict(),
            "opt_g": self.opt_g.state_dict(),
            "opt_d": self.opt_d.state_dict(),
            "schedules": [schedule.state_dict() for schedule in self.schedules],
            "numpy_rng": self.rng.bit_generator.state,
            "torch_rng": torch.get_rng_state(),
        }

    def _restore(self) -> None:
        import torch

        training = self.training.model_dump(mode="json")
        state = read_checkpoint(self.paths["checkpoint"], self.device, training, self.seed)
        self.generator.load_state_dict(state["generator"])
        self.average.load_state_dict(state["average"])
        self.discriminator.load_state_dict(state["discriminator"])
        self.opt_g.load_state_dict(state["opt_g"])
        self.opt_d.load_state_dict(state["opt_d"])
        for schedule, saved in zip(self.schedules, state["schedules"], strict=True):
            schedule.load_state_dict(saved)
        self.epoch, self.history, self.wall_s = state["epoch"], state["history"], state["wall_s"]
        self.rng.bit_generator.state = state["numpy_rng"]
        torch.set_rng_state(state["torch_rng"])

    def _finish(self, validation: list[MapPair]) -> TrainingResult:
        from smokyslam.upsample.weights import logit_offset, save_weights

        start = logit_offset(self.training.occupied_weight)
        offset, calibrated = calibrate(validation, self._logits(validation), start)
        record = {
            "command": self.command,
            "seed": self.seed,
            "epochs": self.epoch,
            "logit_offset": offset,
            "calibrated": calibrated,
            "wall_s": self.wall_s,
            "config": self.training.model_dump(mode="json"),
            "history": self.history,
        }
        save_weights(self.out, self.average.cpu(), self.training.model, offset, record)
        write_config(self.config, self.paths["config"])
        write_history(self.paths["history"], record)
        plot_history(self.paths["plot"], self.history)
        return TrainingResult(self.out, self.history, self.wall_s, calibrated)
