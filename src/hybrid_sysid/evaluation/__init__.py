"""Metrics, run records, tables and figures."""
