"""Simulated smoky buildings: worlds, walking paths, and radar/camera/IMU sensor models."""
