"""A run directory (rundir.RunDir: its layout, saved config, checkpoints, resume check) and its record
(records: metrics.json, never replaced once completed)."""
