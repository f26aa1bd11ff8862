"""Running experiments: one training run over folds, the job processes that run it and
sweeps (local workers or Ray) with their typed events, the run folder's format and
integrity, the workspace index, the per-person study, and what reads a finished run:
its trial table and predictions, the confusion matrix, comparing two runs, re-scoring
one."""
