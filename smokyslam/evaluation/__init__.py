"""Scoring against ground truth: map quality and trajectory accuracy."""
