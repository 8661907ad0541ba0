"""The bottom layer, plain Python that every other layer may use: the one error a bad value raises and the value
checks (checks), every list of allowed values (options), atomic file writers (files), the stop a signal requests
(stop) and the pip command of an optional extra (install)."""
