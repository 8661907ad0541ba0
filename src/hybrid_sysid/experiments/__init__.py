"""Experiments that chain runs inside one job (experiment=transfer, experiment=tuned) or search a space, and what
each adds to its sweep's report (anchored_report, transfer_report, tuned_report: registered with
hybrid_sysid.report.extras when this package is imported, without torch)."""

from hybrid_sysid.experiments import anchored_report, transfer_report, tuned_report  # noqa: F401 - report additions
