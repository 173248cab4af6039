"""Sensor frontends: log readers, radar odometry and camera odometry."""
