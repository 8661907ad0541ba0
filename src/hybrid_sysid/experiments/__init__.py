"""Experiments that chain runs inside one job, which a Hydra sweep cannot: transfer (task=transfer) and tuned
(task=tuned); presets reads the config groups they borrow from."""
