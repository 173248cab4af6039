"""Time series gathered frame by frame and sent to Rerun in columns, a few times a second.

Logging a scalar costs about as much as logging a point cloud; a run has a dozen series at
10-15 Hz. Gathering them and sending each as one column (``rr.send_columns``) keeps the
recording cheap.
"""

from __future__ import annotations

from typing import Any


class SeriesBuffer:
    """``add(entity, sensor_time_s, frame, value)`` per sample, ``flush(rec)`` to send."""

    def __init__(self) -> None:
        self._series: dict[str, tuple[list[float], list[int], list[float]]] = {}

    def add(self, entity: str, sensor_time_s: float, frame: int, value: float) -> None:
        times, frames, values = self._series.setdefault(entity, ([], [], []))
        times.append(sensor_time_s)
        frames.append(frame)
        values.append(float(value))

    def flush(self, rec: Any) -> None:
        """Every gathered sample to ``rec``, one column per series, on both timelines."""
        import rerun as rr

        for entity, (times, frames, values) in self._series.items():
            if values:
                rec.send_columns(
                    entity,
                    indexes=[
                        rr.TimeColumn("sensor_time", timestamp=times),
                        rr.TimeColumn("frame", sequence=frames),
                    ],
                    columns=rr.Scalars.columns(scalars=values),
                )
        self._series.clear()
