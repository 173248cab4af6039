"""Estimation backends: the GTSAM pose graph."""
