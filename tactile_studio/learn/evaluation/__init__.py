"""Evaluation and statistics: metrics, trial predictions from windows, summaries and
plots of a run, the confusion order, re-scoring a run, and comparing two runs with the
significance tests (Wilcoxon over people, McNemar over trials)."""
