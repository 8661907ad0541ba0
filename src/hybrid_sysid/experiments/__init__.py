"""Experiments that chain runs inside one job (experiment=transfer, experiment=tuned) or search a space. What each
experiment adds to its sweep's report is declared in hybrid_sysid.report.extras (EXTRAS, keyed by its name)."""
