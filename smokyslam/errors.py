"""The smokyslam exception hierarchy.

Library code raises these; the CLI turns them into one line on stderr and exit code 1.
Every message names the problem and, where there is one, the offending file or key.
"""


class SmokySlamError(Exception):
    """Base class of every error smokyslam reports to a user."""


class ConfigError(SmokySlamError):
    """A configuration file or option is invalid (unknown key, bad value)."""


class LogError(SmokySlamError):
    """A sensor log cannot be read: missing, not a bag, truncated or corrupt."""


class TopicError(LogError):
    """A topic the run needs is missing from the log."""


class MessageError(LogError):
    """A message in a log is malformed (truncated point cloud, NaN points, bad encoding)."""


class MapFileError(SmokySlamError):
    """A map file (map_server YAML + image) is missing, malformed or inconsistent."""


class MapError(SmokySlamError):
    """A map cannot be built (e.g. poses so far apart that the grid would exceed its limit)."""


class WorldError(SmokySlamError):
    """A simulation world cannot be built (unknown name, unusable floor plan)."""


class TrajectoryFileError(SmokySlamError):
    """A trajectory file (TUM, KITTI) is missing or malformed."""


class EstimationError(SmokySlamError):
    """An estimator failed in a way the caller should report (e.g. a degenerate graph)."""


class RunInterruptedError(SmokySlamError):
    """The user stopped a run (Ctrl-C); what it computed so far was written to ``out_dir``."""

    def __init__(self, out_dir: object) -> None:
        super().__init__(f"interrupted: what was computed so far is in {out_dir}/")
        self.out_dir = out_dir


class RunFailedError(SmokySlamError):
    """A stage failed part-way through a run; what it computed before was written to
    ``out_dir``."""

    def __init__(self, reason: str, out_dir: object) -> None:
        super().__init__(f"{reason} (what was computed before it is in {out_dir}/)")
        self.reason = reason
        self.out_dir = out_dir


class OutputError(SmokySlamError):
    """An output folder cannot be used (it holds an earlier run, or cannot be written)."""


class UpsamplerError(SmokySlamError):
    """The up-sampler cannot be used: its weights are missing, corrupt or not ours, or the map
    gives it nothing to work on."""


class TrainingInterruptedError(UpsamplerError):
    """The user stopped training (Ctrl-C); the last checkpoint is intact."""

    def __init__(self, checkpoint: object, epoch: int) -> None:
        where = f"the checkpoint of epoch {epoch} is {checkpoint}" if epoch else "no epoch done"
        super().__init__(f"interrupted: {where}; rerun with --resume to continue")


class FusionError(SmokySlamError):
    """Maps cannot be registered or fused: one has no known cell, or they cannot overlap."""


class ViewerError(SmokySlamError):
    """A recording cannot be shown: no display, or no recording where one was named."""


class SensorError(SmokySlamError):
    """A sensor cannot be opened, refuses its configuration, or went away."""
