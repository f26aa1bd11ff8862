"""Learning core: datasets, models, training, evaluation, streaming inference."""
