"""Reporting, built from run directories on disk alone: collect (find and read runs), tables (the comparison table
and its marks), summary (a sweep's summary files), figures, the paper's reported figures beside ours, results
pages, and the ``hybrid-sysid-report`` command."""
