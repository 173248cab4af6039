"""The viewer's default layouts, sent with every recording so that it opens useful."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def run_blueprint() -> Any:
    """A run: the world (maps, paths, rig, radar points) beside the camera, cleaned and
    smoked, over the time series (health, smoke and trust, error so far)."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name="world", origin="world"),
            rrb.Vertical(
                rrb.Horizontal(
                    rrb.Spatial2DView(name="camera (smoked)", origin="world/map/rig/camera/image"),
                    rrb.Spatial2DView(name="camera (cleaned)", origin="camera/clean"),
                ),
                rrb.TimeSeriesView(name="health", origin="health"),
                rrb.TimeSeriesView(name="smoke and trust", contents=["smoke/**", "trust/**"]),
                rrb.TimeSeriesView(name="error so far [m]", origin="error"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def compare_blueprint(map_names: Sequence[str] = ()) -> Any:
    """Several runs: every path over the true map, each run's error over time, and the named
    maps (``maps/<name>``) as tabs."""
    import rerun.blueprint as rrb

    right = [rrb.TimeSeriesView(name="error [m]", origin="error")]
    if map_names:
        tabs = [rrb.Spatial2DView(name=name, origin=f"maps/{name}") for name in map_names]
        right.append(rrb.Tabs(*tabs))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name="every source", origin="world"),
            rrb.Vertical(*right),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )
