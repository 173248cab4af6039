"""Occupancy grids: ray casting, radar stitching, visual flattening, map pictures."""
