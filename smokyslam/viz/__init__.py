"""Visualization: the Rerun recording of a run (rerun is imported only here)."""
