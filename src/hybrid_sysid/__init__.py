"""hybrid-sysid: labelled vs physics-informed (hybrid) objectives for parameter identification.

Layers, bottom up: ``physics`` (plain numpy), ``data`` (cached datasets, LightningDataModule),
``model`` (CNNs, objectives, LightningModule), ``evaluation`` (metrics, tables, figures),
``train`` (the Hydra entry point).
"""

__version__ = "0.1.0"


def __getattr__(name):
    # `import hybrid_sysid.physics` runs this file and must stay numpy-only: torch loads only when asked for
    if name == "load_estimator":
        from hybrid_sysid.estimator import load_estimator
        return load_estimator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
