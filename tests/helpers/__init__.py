"""What several test folders share: the app in a process of its own (app_process), the processes the tests start
early (started_early), a tiny trained run (estimator_run), the paper's prior of p (paper_prior) and stand-ins for a
run's evaluation (evaluation_fakes)."""
