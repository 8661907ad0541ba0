"""The command-line entry points (hybrid-sysid, hybrid-sysid-eval, hybrid-sysid-predict, hybrid-sysid-report):
what a command's process does with signals and exit statuses (process), what each job goes through (job: the
preflight, run_job), the sweep's callback and progress lines (sweep, progress), the key=value parser that report
and predict share (arguments), a search's driver (search)."""
