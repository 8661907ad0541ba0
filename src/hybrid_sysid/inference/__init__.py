"""A trained run as a tool on recordings users bring: loading it (loading: load_estimator), the estimator
(estimator), its inputs and memory bound (inputs, memory), the flags on estimates not to trust (flags) and the
file readers (readers)."""
