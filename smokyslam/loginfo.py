"""Plain-text summary of a sensor log, as printed by ``smokyslam info``."""

from __future__ import annotations

from smokyslam.frontends.readers.base import LogSummary


def format_summary(summary: LogSummary) -> str:
    """A table of topics (type, message count, rate in Hz) under a header with the duration.

    Rates of topics with fewer than two messages print as ``-``. Pure: no I/O.
    """
    header = [
        f"log:      {summary.path}",
        f"format:   {summary.format}",
        f"duration: {summary.duration_s:.2f} s",
        f"messages: {sum(stream.count for stream in summary.streams)}",
    ]
    rows = [("topic", "type", "count", "rate Hz")]
    for stream in summary.streams:
        rate = f"{stream.rate_hz:.1f}" if stream.count > 1 and stream.rate_hz > 0 else "-"
        rows.append((stream.topic, stream.msgtype, str(stream.count), rate))
    widths = [max(len(row[col]) for row in rows) for col in range(4)]
    lines = [
        f"{topic:<{widths[0]}}  {msgtype:<{widths[1]}}  {count:>{widths[2]}}  {rate:>{widths[3]}}"
        for topic, msgtype, count, rate in rows
    ]
    if not summary.streams:
        lines.append("(no topics)")
    if summary.damage:
        lines += ["", summary.damage]
    return "\n".join([*header, "", *lines]) + "\n"
