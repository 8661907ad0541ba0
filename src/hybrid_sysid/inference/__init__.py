"""A trained run as a tool on recordings users bring: the estimator (load_estimator) and the file readers."""
