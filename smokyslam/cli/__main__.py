"""``python -m smokyslam.cli``."""

from smokyslam.cli import main

main()
