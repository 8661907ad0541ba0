"""Reporting, built from run directories on disk alone: the sweep summary (collect, tables, figures), the
paper's reported figures beside ours, results pages, and the ``hybrid-sysid-report`` command."""
