"""Reporting, built from run directories on disk alone: collect (find and read runs), tables, stats, markdown and
latex (the comparison table, its marks and its two forms), summary (a sweep's summary files), figures, the
paper's reported figures beside ours, results pages, and what an experiment adds to its table (extras)."""
