"""Data and views: trials read from sessions, the views a model is fed (resampled, windows,
slices), windowing and its aggregation, the feature cache, augmentation, hand features,
the splits (LOPO, shots) and the touch statistics the simulator is judged by."""
