"""Run and sweep directories, read and written here alone: their file names (layout), a run's files and its record
(rundir: RunDir), resuming it (resume), the one-writer lock (locks), a sweep's record of itself
(sweepdir) and what made a run's numbers (provenance: the commit and the CPU)."""
