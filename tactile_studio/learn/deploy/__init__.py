"""Deployment: exporting a run's models (ONNX, TorchScript), streaming prediction over a
live feed, live inference with its running calibration, the fold model predicting over a
recording or a live feed (window_model), and few-shot personalisation
with labelled touches (personalise) that the experimenter prompts (touch_prompts)."""
