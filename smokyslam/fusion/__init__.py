"""Map fusion: registering occupancy maps onto each other, then fusing them."""
