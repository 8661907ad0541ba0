"""hybrid-sysid: labelled vs physics-informed (hybrid) objectives for parameter identification.

Layers, each importing only those before it: ``physics`` (plain numpy), ``data`` (cached datasets, the split by
road, the LightningDataModule), ``model`` (CNNs, objectives, LightningModule, metrics) and ``baselines`` (least
squares without a network), training (``config``, ``train``, ``records``), ``report`` (summaries, tables,
figures, the ``hybrid-sysid-report`` command), ``app`` (the Hydra app behind ``hybrid-sysid``); beside the last
two, ``estimator`` (a trained run as a tool: ``load_estimator``) and ``predict`` (the ``hybrid-sysid-predict``
command). ``files`` holds the atomic writer any layer may use. docs/design.md describes each.
"""

__version__ = "0.2.0"


def __getattr__(name):
    # `import hybrid_sysid.physics` runs this file and must stay numpy-only: torch loads only when asked for
    if name == "load_estimator":
        from hybrid_sysid.inference.loading import load_estimator

        return load_estimator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
