"""The bottom layer, plain Python that every other layer may use: atomic file writers (files), the one-line value
checks (checks) and every list of allowed values (options)."""
