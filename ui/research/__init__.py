"""The research workspace window: sessions, runs, the linked confusion matrix, comparison."""
