"""The arguments every built-in data module takes of a run's config and objective (training.build's simulated
one, training.recordings' files), in one place."""

from __future__ import annotations

from omegaconf import DictConfig


def window_arguments(cfg: DictConfig, objective=None) -> dict:
    """What every built-in data module takes of the config and the objective: the window, the batches, their
    noise, and the signals the objective reads (its band-pass, its outside fit)."""
    return dict(
        window=cfg.data.window,
        batch_size=cfg.model.batch_size,
        train_std=cfg.noise.train_std,
        seed=cfg.seed,
        integration=cfg.data.integration,
        fir=None if objective is None else objective.fir,
        train_std_max=cfg.noise.get("train_std_max"),
        outside_fir=None if objective is None else objective.outside_fir,
        # an objective of a plugin need not declare a target: its outside fit, if any, is least squares
        outside_target=getattr(objective, "outside_target", None),
        outside_fix=getattr(objective, "outside_fix", "none"),
    )
