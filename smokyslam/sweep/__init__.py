"""``smokyslam sweep``: many runs over worlds, smoke levels, sources and configs, on Dask."""
