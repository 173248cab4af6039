"""Config of ``smokyslam localize``: Monte Carlo localization in a saved map."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from smokyslam.config.base import Section as _Section


class LocalizeConfig(_Section):
    """The likelihood field (``localize/likelihood.py``), the particle filter
    (``localize/mcl.py``), the tracking start and what counts as converged."""

    min_particles: int = Field(200, ge=10, description="KLD's lower bound on the particles")
    max_particles: int = Field(2000, ge=10, description="KLD's upper bound; a global start")
    global_candidates: int = Field(
        20,
        ge=1,
        description="uniform poses drawn per particle placed globally or injected; the scan's"
        " likelihood picks among them",
    )
    kld_epsilon: float = Field(0.05, gt=0.0, description="KLD's bound on the posterior error")
    kld_bin_m: float = Field(0.25, gt=0.0, description="KLD histogram cell, metres")
    kld_bin_deg: float = Field(10.0, gt=0.0, description="KLD histogram cell, degrees")
    alpha_slow: float = Field(0.001, gt=0.0, lt=1.0, description="augmented MCL's long average")
    alpha_fast: float = Field(0.1, gt=0.0, lt=1.0, description="augmented MCL's short average")
    motion_scale: float = Field(
        4.0, gt=0.0, description="variance multiplier on the odometry's reported covariance"
    )
    points_weight: float = Field(
        0.1, gt=0.0, le=1.0, description="exponent on each point's likelihood (points correlate)"
    )
    resample_ess: float = Field(
        0.5,
        gt=0.0,
        le=1.0,
        description="resample when the effective sample size falls below"
        " this share of the particles",
    )
    camera_motion: bool = Field(
        True,
        description="with a camera in the log, its odometry joins the motion steps while it is"
        " healthy (made metric, checked and weighed as SLAM's camera factors are)",
    )
    hit_sigma_m: float = Field(0.3, gt=0.0, description="likelihood field: wall distance sigma")
    z_hit: float = Field(0.8, ge=0.0, le=1.0, description="likelihood field: share of hits")
    z_rand: float = Field(0.2, ge=0.0, le=1.0, description="likelihood field: share of clutter")
    max_range_m: float = Field(10.0, gt=0.0, description="likelihood field: clutter's range")
    p_unknown: float = Field(
        0.1,
        gt=0.0,
        description="likelihood of a point off the map, and the least of one in unknown space",
    )
    p_unknown_tracking: float = Field(
        0.3,
        gt=0.0,
        description="the same while tracking from a given start (a search keeps p_unknown):"
        " near a trusted pose, a point in unknown space most likely hit something unmapped;"
        " free cells at unknown space's edge get it too, faded by their distance to it"
        " (a Gaussian of hit_sigma_m)",
    )
    ray_check_m: list[float] = Field(
        [0.2, 0.4],
        description="distances before each point along its ray (from the radar) where the map"
        " should not be occupied: a return is the first surface on its ray. [] turns it off",
    )
    ray_blocked: float = Field(
        0.3,
        gt=0.0,
        le=1.0,
        description="factor on a point's likelihood for each of those places the map has"
        " occupied (its ray went through a wall)",
    )
    inject_weight: float = Field(
        0.1,
        gt=0.0,
        le=1.0,
        description="weight of a particle injected by augmented MCL against one resampled: a"
        " prior against jumps; the injected place must out-fit the cloud for a few scans",
    )
    init_sigma_m: float = Field(1.0, gt=0.0, description="tracking start: position sigma")
    init_sigma_deg: float = Field(15.0, gt=0.0, description="tracking start: heading sigma")
    init_sigma_cut: float = Field(
        2.5,
        ge=1.0,
        description="tracking start: particles drawn within this many sigmas (the position"
        " radially, the heading apart), a truncated Gaussian. Untruncated, the few particles"
        " 3-4 sigmas out landed on a warehouse's neighbouring rack aisle, which the first"
        " scans can favour",
    )
    converged_m: float = Field(
        0.3, gt=0.0, description="converged: position error at most this from then on"
    )
    converged_deg: float = Field(
        10.0, gt=0.0, description="converged: heading error at most this from then on"
    )
    settle_s: float = Field(
        5.0, ge=0.0, description="errors after this many seconds are reported apart"
    )
    densify: Literal["auto", "always", "never"] = Field(
        "auto",
        description="up-sample the map with the shipped generator before localizing in it"
        " (auto: a map as sparse as a stitched radar map; localize/map_prior.py)",
    )
    densify_isolated: float = Field(
        0.15,
        ge=0.0,
        le=1.0,
        description="auto: densify when at least this share of the occupied cells have no"
        " occupied neighbour (sparse radar maps 0.24-0.46, others at most 0.08)",
    )
    seed: int = Field(0, description="the filter's random numbers")

    @model_validator(mode="after")
    def _ordered(self) -> LocalizeConfig:
        if self.min_particles > self.max_particles:
            raise ValueError("min_particles must not exceed max_particles")
        if any(d <= 0 for d in self.ray_check_m):
            raise ValueError("ray_check_m distances must be positive")
        return self
