"""Learners: the contract every model family satisfies, the forest and k-NN baselines, the
torch training loop and the learner that wraps a registered network, fused models,
adaptation to a person, and the conformance checks a new model must pass."""
