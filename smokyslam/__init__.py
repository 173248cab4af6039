"""smokyslam: radar-visual SLAM for smoke-filled buildings."""

__version__ = "0.1.0"
