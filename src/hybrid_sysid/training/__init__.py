"""The training layer: build a run from its config (build), run it (run: train, a baseline, a checkpoint on
other data), score it (evaluation), its Lightning callbacks (callbacks) and experiment trackers (tracking)."""
