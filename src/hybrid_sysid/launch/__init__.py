"""What a command's process does around its jobs: signals and exit statuses (process, state), each job's
preflight and records (job), orphaned workers (orphans), a sweep's callback, progress lines and time left
(sweep, progress, time_left), a search's driver and its study (search, study), the SLURM launcher and the
partition's limits (slurm, slurm_limits), the console (console), and the command line as Hydra reads it
(overrides, choices). The commands in hybrid_sysid.cli parse, call this and print."""
