"""hybrid-sysid: labelled vs physics-informed (hybrid) objectives for parameter identification.

Layers, bottom up: ``physics`` (plain numpy), ``data`` (cached datasets, LightningDataModule),
``model`` (CNNs, objectives, LightningModule), ``evaluation`` (metrics, tables, figures),
``train`` (the Hydra entry point).
"""

__version__ = "0.1.0"
