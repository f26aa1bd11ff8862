"""Evaluation: the measures and figures of a run, below the runs that record them:
metrics, summaries (metrics.json), the paired significance tests (Wilcoxon over people,
McNemar over trials) and plots."""
