"""Every list of allowed values a config key takes, in one leaf module without numpy or torch: the objects that
own a value check it against these, and the config's checks (hybrid_sysid.config.validate) run in a process
that has not loaded torch (a sweep's parent, a refused command line)."""

# hybrid_sysid.data.windows.WindowCutter: how a window's sensor noise is re-integrated (docs/noise.md)
INTEGRATIONS = ("t0", "window")
# hybrid_sysid.data.spec.DatasetSpec: the road amplitude's form (docs/design.md, "Road")
AMPLITUDES = ("paper", "iso")
# hybrid_sysid.model.objectives.HybridObjective
WEIGHTINGS = ("none", "eiv")
# what the hybrid objective fits the prediction to: the residual itself, or the per-window least-squares fit of
# the residual's regressors (plain or in a metric whitened by their correlation)
TARGETS = ("residual", "least_squares", "whitened")
FILTER_KEYS = ("low_hz", "high_hz", "taps")
NORMS = ("l1", "l2")
# hybrid_sysid.model.networks: activation name -> torch.nn class name; FastCNN's downsampling
ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU", "none": "Identity"}
DOWNSAMPLES = ("pool", "stride")
# hybrid_sysid.model.module.IdentificationModule: optimiser name -> torch.optim class name; schedules
OPTIMIZERS = {"adam": "Adam", "adamw": "AdamW"}
SCHEDULES = ("constant", "onecycle", "cosine")
# trainer.monitor: the validation figure that selects the best checkpoint (auto: by the objective)
MONITORS = ("auto", "val/loss", "val/rel_dev", "val/p1_rel_dev", "val/p2_rel_dev")
# trainer.profiler: Lightning's profilers (null: none), their report written into the run directory
PROFILERS = ("simple", "advanced")
# hybrid_sysid.baselines.LeastSquaresFit
SPANS = ("window", "series")
FILTERS = ("none", "bandpass")
UNKNOWNS = ("p", "m3")
# what one job of hybrid-sysid does (hybrid_sysid.cli.train): one run, a transfer chain, a tuned comparison
TASKS = ("train", "transfer", "tuned")
