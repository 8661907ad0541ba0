"""Every list of values a key may take, in one leaf module without numpy or torch: the objects that own a value
check it against these (core.checks.check_choice), and the config's checks run in a process that has not loaded
torch (a sweep's parent, a refused command line)."""

# hybrid_sysid.physics: the road classes of ISO 8608 the paper uses (eq. 5), and how a recording is measured
ROAD_CLASSES = "ABCDE"
MEASUREMENTS = ("paper", "consistent", "continuous")
STEPPED = ("paper", "consistent")  # the measurements recorded from the eq.-11 step (continuous: exact samples)
DEFAULT_MEASUREMENT = "consistent"
# hybrid_sysid.data.windows.WindowCutter: how a window's sensor noise is re-integrated (docs/noise.md), and the rules
# that integrate a recording's samples (symplectic Euler for the stepped measurements, the trapezoid for continuous)
INTEGRATIONS = ("t0", "window")
INTEGRATION_RULES = ("symplectic", "trapezoid")
# hybrid_sysid.data.splits: the splits of a dataset, by road
SPLITS = ("train", "val", "test")
# hybrid_sysid.model.objectives.HybridObjective: the residual's weighting, and what it fits the prediction to (the
# residual itself, or the per-window least-squares fit of its regressors, plain or whitened by their correlation)
WEIGHTINGS = ("none", "eiv")
TARGETS = ("residual", "least_squares", "whitened")
# hybrid_sysid.data.outside: the fit of the samples outside the window (objective=cross_segment's target)
OUTSIDE_TARGETS = ("eiv", "ls")
FILTER_KEYS = ("low_hz", "high_hz", "taps")
# hybrid_sysid.model.networks: activation name -> torch.nn class name; FastCNN's downsampling
ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU", "none": "Identity"}
DOWNSAMPLES = ("pool", "stride")
# hybrid_sysid.model.optim.OptimSettings: optimiser name -> torch.optim class name; learning-rate schedules
OPTIMIZERS = {"adam": "Adam", "adamw": "AdamW"}
SCHEDULES = ("constant", "onecycle")
# trainer.monitor: the validation figure that selects the best checkpoint (auto: the objective's own)
MONITORS = ("auto", "val/loss", "val/rel_dev", "val/p1_rel_dev", "val/p2_rel_dev")
# trainer.profiler: Lightning's profilers (null: none), their report written into the run directory
PROFILERS = ("simple", "advanced")
# hybrid_sysid.baselines.LeastSquaresFit
SPANS = ("window", "series")
FILTERS = ("none", "bandpass")
UNKNOWNS = ("p", "m3")
# the package's own classical fixes of a recording fault; what a fit accepts is the registry's, these and a
# registered fault's own (physics.faults.fixes, which checks baseline.fix)
FIXES = ("none", "gain", "skew", "hardening")
# the Lightning classes a config may name by _target_ (hybrid_sysid.config.targets): loggers and callbacks
LOGGERS = ("CSVLogger", "TensorBoardLogger", "MLFlowLogger")
CALLBACKS = ("EarlyStopping", "ModelSummary", "RichModelSummary", "RichProgressBar", "TQDMProgressBar")
# hybrid-sysid-eval: the config sections an evaluation may change (the network and its training are the run's);
# tags label the evaluation's own record (without, it keeps the trained run's)
EVAL_OVERRIDABLE = ("data", "car", "road", "noise", "sensor", "evaluation", "paths", "tags")
# hybrid-sysid-report metric=: what a table's cells show, and its words
METRICS = {"mean_rel_dev": "mean relative deviation", "std_rel_dev": "std of relative deviation"}
# what one job of hybrid-sysid does (hybrid_sysid.cli.train): one run, a transfer chain, a tuned comparison
TASKS = ("train", "transfer", "tuned")
DIRECTIONS = ("minimize", "maximize")  # a search's direction (hybrid_sysid.experiments.search)
