"""The command-line entry points (hybrid-sysid, hybrid-sysid-eval, hybrid-sysid-predict, hybrid-sysid-report) and
the job wrapper they share (job.run_job)."""
