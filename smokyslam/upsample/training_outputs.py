"""What training leaves beside the weights: paths, the history as JSON, a loss plot."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def artefact_paths(out: Path) -> dict[str, Path]:
    """Where training writes what, beside the weights file ``out``."""
    stem = out.with_suffix("")
    return {
        "checkpoint": stem.with_name(stem.name + ".ckpt"),
        "config": stem.with_name(stem.name + ".config.yaml"),
        "history": stem.with_name(stem.name + ".history.json"),
        "plot": stem.with_name(stem.name + ".loss.png"),
        "data": stem.with_name(stem.name + ".data"),
    }


def write_history(path: Path, record: dict[str, Any]) -> Path:
    path.write_text(json.dumps(record, indent=2) + "\n")
    return path


def plot_history(path: Path, history: list[dict[str, float]]) -> Path:
    """Generator terms and discriminator loss (left), validation error index of the dense
    and the sparse maps (right), per epoch."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epochs = [h["epoch"] for h in history]
    fig, (losses, validation) = plt.subplots(1, 2, figsize=(11, 4))
    terms = (
        ("bce", "cross-entropy"),
        ("l1", "L1"),
        ("line", "line prior"),
        ("adversarial", "adversarial"),
    )
    for key, label in terms:
        losses.plot(epochs, [h[key] for h in history], label=label)
    losses.plot(epochs, [h["loss_d"] for h in history], label="discriminator", linestyle="--")
    losses.set_xlabel("epoch")
    losses.set_yscale("log")
    losses.set_title("training losses")
    losses.legend()
    validation.plot(epochs, [h["val_error_index"] for h in history], label="dense (GAN)")
    validation.plot(
        epochs, [h["val_sparse_error_index"] for h in history], label="sparse", linestyle="--"
    )
    validation.set_xlabel("epoch")
    validation.set_ylabel("error index (observed truth)")
    validation.set_title("validation worlds")
    validation.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
