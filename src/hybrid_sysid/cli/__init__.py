"""The command-line entry points (hybrid-sysid, hybrid-sysid-eval, hybrid-sysid-predict, hybrid-sysid-report):
each parses its arguments, calls the work and prints. What a command's process does around its jobs (signals,
exit statuses, the preflight, sweeps, SLURM) is hybrid_sysid.launch; the key=value parser that report and
predict share is ``arguments``."""
