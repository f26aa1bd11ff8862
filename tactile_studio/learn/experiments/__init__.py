"""Running experiments: one training run over folds, the job processes that run it and
sweeps (local workers or Ray) with their typed events, the run folder's format and
integrity, the workspace index, and the per-person study."""
