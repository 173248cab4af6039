"""Real sensors: the TI mmWave radar's UART frames and its ``.cfg`` files."""
