"""Up-sampler weights files: a header we check, the model's shape, the training record.

A weights file is a ``torch.save`` of a plain dict (read back with ``weights_only=True``, so
loading never runs code from the file): ``format`` = :data:`FORMAT`, ``version``, ``model``
(the ``UpsamplerModelConfig`` it was built with), ``state_dict``, ``logit_offset`` (added to
the generator's logits at inference: ``-log(occupied_weight)`` undoes the weight training gave
wall cells, so the sigmoid reads as a probability again) and ``training`` (command, config and
validation curve). The shipped weights live in ``smokyslam/weights/``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from smokyslam.config.upsample import UpsamplerModelConfig
from smokyslam.errors import UpsamplerError

FORMAT = "smokyslam-upsampler"
VERSION = 1
SHIPPED_NAME = "upsampler.pt"


@dataclass
class UpsamplerWeights:
    """A generator ready for inference, and where it came from."""

    generator: Any  # UNetGenerator, in eval mode
    model: UpsamplerModelConfig
    logit_offset: float
    training: dict[str, Any] = field(default_factory=dict)
    path: Path | None = None


def shipped_weights_path() -> Path:
    """The weights inside the package (made by ``smokyslam train-upsampler``)."""
    return Path(str(resources.files("smokyslam") / "weights" / SHIPPED_NAME))


def logit_offset(occupied_weight: float) -> float:
    """What inference adds to the logits of a generator trained with wall cells weighted
    ``occupied_weight``: a weighted cross-entropy's optimum is the odds times the weight."""
    return -math.log(occupied_weight)


def save_weights(
    path: Path | str,
    generator: Any,
    model: UpsamplerModelConfig,
    offset: float,
    training: dict[str, Any],
) -> Path:
    """Write ``generator``'s weights with our header, atomically (a crash leaves no half
    file)."""
    import torch

    path = Path(path)
    state = {k: v.detach().cpu().clone() for k, v in generator.state_dict().items()}
    payload = {
        "format": FORMAT,
        "version": VERSION,
        "model": model.model_dump(),
        "state_dict": state,
        "logit_offset": float(offset),
        "training": training,
    }
    partial = path.with_name(path.name + ".partial")
    torch.save(payload, partial)
    os.replace(partial, path)
    return path


def load_weights(path: Path | str | None = None) -> UpsamplerWeights:
    """The generator of a weights file (None: the shipped one). Anything that is not a
    complete file of ours is an UpsamplerError naming the problem."""
    import torch

    from smokyslam.upsample.model import UNetGenerator

    path = Path(path) if path is not None else shipped_weights_path()
    if not path.is_file():
        raise UpsamplerError(f"{path}: no such weights file")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many kinds for a damaged or foreign file
        raise UpsamplerError(
            f"{path}: not a readable weights file (corrupt or truncated: {type(exc).__name__})"
        ) from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise UpsamplerError(f"{path}: not a smokyslam up-sampler weights file")
    if payload.get("version") != VERSION:
        raise UpsamplerError(
            f"{path}: weights format version {payload.get('version')}, this smokyslam reads "
            f"{VERSION}"
        )
    try:
        model = UpsamplerModelConfig(**payload["model"])
        generator = UNetGenerator(model.base_channels, model.depth, model.max_channels)
        generator.load_state_dict(payload["state_dict"])
        offset = float(payload["logit_offset"])
    except Exception as exc:
        raise UpsamplerError(
            f"{path}: the weights do not fit the model they name ({type(exc).__name__})"
        ) from None
    generator.eval()
    return UpsamplerWeights(generator, model, offset, dict(payload.get("training") or {}), path)
