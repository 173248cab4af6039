"""The gyro bias from scan matching's yaw against the age of the map points it matched.

The heading filter (``motion_prior.HeadingFilter``) takes each registration as a yaw
measurement against a fixed map. The local map is not fixed: it is built from the poses
the registrations give, so it turns with their heading error, and a registration only says
how far the heading drifted since the map points it matched were inserted. The filter
therefore sees a small part of the drift, grows confident early, and on long walks keeps a
bias estimate far from the truth (120 s warehouses: +0.02 deg/s against -0.16).

This estimator uses that age. Every local-map point keeps its insertion stamp and the
heading offset then: the registered yaw less the raw gyro integral. A frame's scan-only yaw
(its registered yaw with the motion prior's share taken out, as the heading filter recovers
it) less the raw gyro integral, against the mean offset of the map points it matched
(weighted by their yaw information), differs by ``-bias * age``, ``age`` the time since their
mean insertion stamp, plus scan noise. A weighted least-squares line through the origin over
every frame so far is the bias estimate; its weights are the filter's (scan variance,
inflated for registrations within ``decorrelation_s`` of each other).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.geometry import wrap_angle

MIN_AGE_S = 0.05
"""Matches against points younger than this say nothing of the bias."""


@dataclass(frozen=True)
class MapAge:
    """What a frame's registration matched, averaged over its matched points by their yaw
    information: ``stamp_s``, their mean insertion stamp; ``heading_offset_rad``, their mean
    heading offset (registered yaw less raw gyro integral when they were inserted)."""

    stamp_s: float
    heading_offset_rad: float


@dataclass(frozen=True)
class ScanYaw:
    """A registration's yaw without the motion prior's share: ``innovation_rad`` from the
    prior's yaw, and its variance ``variance_rad2``."""

    innovation_rad: float
    variance_rad2: float

    def decorrelated_variance(self, decorrelation_s: float, dt_s: float) -> float:
        """The variance inflated for the registrations within ``decorrelation_s`` that share
        this one's map (frames ``dt_s`` apart): together they count as one measurement."""
        return self.variance_rad2 * max(1.0, decorrelation_s / max(dt_s, 1e-6))


def scan_yaw(prior_var: float, posterior_var: float, innovation_rad: float) -> ScanYaw | None:
    """The scan-only yaw of a registration solved with a yaw prior of ``prior_var`` that moved
    ``innovation_rad`` from it with ``posterior_var`` left; None when the scan added nothing.

    Fusing a prior with a scan measurement shrinks the variance by the scan's share, which
    gives the scan's variance and, dividing the move by that share, its own innovation.
    """
    if not 0.0 < posterior_var < prior_var * (1.0 - 1e-6):
        return None
    shrink = 1.0 - posterior_var / prior_var
    return ScanYaw(innovation_rad / shrink, 1.0 / (1.0 / posterior_var - 1.0 / prior_var))


class MapAgeBias:
    """Least-squares gyro bias (rad/s) from per-frame ``add``; ``bias_radps`` once its nominal
    sigma is below ``ready_sigma_radps`` (None before)."""

    def __init__(self, decorrelation_s: float, ready_sigma_radps: float) -> None:
        self._decorrelation_s = decorrelation_s
        self._ready_sigma_radps = ready_sigma_radps
        self._sum_rt = 0.0
        self._sum_tt = 0.0

    @property
    def estimate_radps(self) -> float | None:
        """The fitted bias whatever its sigma; None before any frame counted."""
        return -self._sum_rt / self._sum_tt if self._sum_tt > 0.0 else None

    @property
    def sigma_radps(self) -> float:
        """Nominal sigma of the fit (inf before any frame counted)."""
        return 1.0 / np.sqrt(self._sum_tt) if self._sum_tt > 0.0 else np.inf

    @property
    def bias_radps(self) -> float | None:
        """The fitted bias once its sigma is small enough to use, else None."""
        return self.estimate_radps if self.sigma_radps < self._ready_sigma_radps else None

    def add(
        self,
        stamp_s: float,
        scan_heading_offset_rad: float,
        scan: ScanYaw,
        dt_s: float,
        matched: MapAge,
    ) -> None:
        """One frame at ``stamp_s``: its scan-only yaw less the raw gyro integral
        (``scan_heading_offset_rad``), the scan yaw's variance, the frame interval, and what
        it matched."""
        age_s = stamp_s - matched.stamp_s
        residual = float(wrap_angle(scan_heading_offset_rad - matched.heading_offset_rad))
        if not (np.isfinite(age_s) and np.isfinite(residual)) or age_s <= MIN_AGE_S:
            return  # too young to tell, or a frame without gyro samples in between
        variance = scan.decorrelated_variance(self._decorrelation_s, dt_s)
        self._sum_rt += residual * age_s / variance
        self._sum_tt += age_s * age_s / variance
