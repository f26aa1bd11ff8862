"""Running experiments: one training run over folds, the job processes that run it and
sweeps (local workers or Ray) with their typed events, the run folder's format and
integrity, its trial table, and the per-person study. What reads a finished run
back (predictions, confusion, comparison, re-scoring, the workspace index) is the
room above, learn/results."""
