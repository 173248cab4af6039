"""Training checkpoints of the up-sampler: written whole, then renamed; read back checked.

A checkpoint is a ``torch.save`` of a plain dict (read with ``weights_only=True``) holding
``kind`` = :data:`KIND`, the training config and seed it was made with, and the trainer's
whole state (networks, optimisers, schedules, random generators, history).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from smokyslam.errors import UpsamplerError

KIND = "smokyslam-upsampler-checkpoint"


def write_checkpoint(path: Path, state: dict[str, Any]) -> Path:
    """Write ``state`` to ``path``; a Ctrl-C before the rename leaves the last one whole."""
    import torch

    partial = path.with_name(path.name + ".partial")
    torch.save({"kind": KIND, **state}, partial)
    os.replace(partial, path)
    return path


def read_checkpoint(path: Path, device: Any, training: dict[str, Any], seed: int) -> dict[str, Any]:
    """The state at ``path``, made with the ``training`` config (the number of epochs may
    differ) and ``seed``; UpsamplerError naming the problem otherwise."""
    import torch

    if not path.is_file():
        raise UpsamplerError(f"--resume: no checkpoint at {path}")
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except Exception as exc:  # torch raises many kinds for a damaged or foreign file
        raise UpsamplerError(f"{path}: unreadable checkpoint ({type(exc).__name__})") from None
    if not isinstance(state, dict) or state.get("kind") != KIND:
        raise UpsamplerError(f"{path}: not a smokyslam up-sampler checkpoint")
    theirs = dict(state["training"])
    if {**theirs, "epochs": 0} != {**training, "epochs": 0} or state["seed"] != seed:
        raise UpsamplerError(
            f"{path}: made with another training config or seed; remove it or drop --resume"
        )
    return state
