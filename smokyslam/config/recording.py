"""Config of the Rerun recording (``--rerun``): what is logged, and how often."""

from __future__ import annotations

from pydantic import Field

from smokyslam.config.base import Section as _Section


class RecordingConfig(_Section):
    """Rates of the recording. Radar points and the rig's pose are logged every radar frame;
    the rest at these rates, so that recording keeps the run fast and the file small."""

    camera_every: int = Field(
        1, ge=1, description="log every n-th tracked camera frame (raw, cleaned, features)"
    )
    jpeg_quality: int = Field(80, ge=10, le=100, description="camera images are stored as JPEG")
    path_period_s: float = Field(
        1.0, gt=0.0, description="sensor seconds between logs of the graph's path and keyframes"
    )
    maps_period_s: float = Field(
        5.0, gt=0.0, description="sensor seconds between logs of the growing grid maps"
    )
