"""The sizes every learner, network or baseline, comes in; ``full`` (the paper's) is the
default and ``tiny`` is for CPU tests.

Its own module, below learn's rooms and free of torch: the model spec (models/), the
learner contract (learners/), the CLI and the research workspace's choices all read it.
"""

PRESETS = ("full", "tiny")
