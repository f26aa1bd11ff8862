"""Model benchmarks on the CPU with 2 threads: parameters, batch-1 latency (torch, onnxruntime,
int8 ONNX) and file sizes, the CNN-Transformer streaming predictor per new frame, and
training throughput.

Run: .venv/bin/python benchmarks/bench_models.py [--quick] [--no-onnx]
(--quick: tiny presets only). Prints tables; asserts nothing. The paper's goal for the
streaming CNN-Transformer is <= 1.3 ms per prediction (their desktop GPU figure).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tactile_studio.learn.deploy.export import (  # noqa: E402
    export_onnx,
    int8_format,
    load_onnx_predictor,
    model_size_bytes,
    quantize_onnx_int8,
)
from tactile_studio.learn.deploy.streaming import StreamingPredictor  # noqa: E402
from tactile_studio.learn.models import MODELS  # noqa: E402
from tactile_studio.learn.models._common import count_parameters  # noqa: E402

THREADS = 2
N_CLASSES = 9
# (channels, grid) each model is measured at: the paper's input first
CONFIGS = {
    "cnn3d": [(3, (11, 11))],
    "cnn_transformer": [(1, (8, 8)), (3, (6, 6))],
    "cnn1d": [(1, (6, 6))],
    "mts3d": [(3, (6, 6))],
    "sefusion": [(3, (6, 6))],
}


def timed(fn, budget_s: float = 1.5, min_runs: int = 5, max_runs: int = 300) -> list[float]:
    """Per-call seconds of ``fn`` (after one warm-up), until the time budget is used."""
    fn()
    times: list[float] = []
    start = time.perf_counter()
    while len(times) < max_runs and (len(times) < min_runs
                                     or time.perf_counter() - start < budget_s):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times


def ms(times: list[float]) -> str:
    med = statistics.median(times) * 1e3
    p95 = float(np.percentile(times, 95)) * 1e3
    return f"{med:8.2f} {p95:8.2f}"


def bench_inference(name: str, preset: str, channels: int, grid, onnx: bool) -> None:
    spec = MODELS[name]
    model = spec.build(N_CLASSES, channels, grid, preset).eval()
    x = torch.randn(1, *model.input_shape)
    with torch.inference_mode():
        t_torch = timed(lambda: model(x))
    row = (f"{name:16s} {preset:5s} {channels}x{grid[0]}x{grid[1]:<3d} "
           f"{count_parameters(model):>10,d} {model_size_bytes(model) / 1e6:8.2f}MB "
           f"torch {ms(t_torch)}")
    if onnx:
        with tempfile.TemporaryDirectory() as tmp:
            path = export_onnx(model, x, Path(tmp) / "m.onnx")
            predict = load_onnx_predictor(path, threads=THREADS)
            xn = x.numpy()
            row += f" | ort {ms(timed(lambda: predict(xn)))} {path.stat().st_size / 1e6:6.2f}MB"
            if spec.quantizable:
                # random z-scored-like calibration: sizes and latency, not accuracy
                calib = np.random.default_rng(0).normal(size=(64, *model.input_shape))
                q = quantize_onnx_int8(path, Path(tmp) / "q.onnx", calib,
                                       quant_format=int8_format(name))
                q8 = load_onnx_predictor(q, threads=THREADS)
                row += f" | int8 {ms(timed(lambda: q8(xn)))} {q.stat().st_size / 1e6:6.2f}MB"
    print(row, flush=True)


def bench_streaming(preset: str, channels: int, grid, variant: str = "torch") -> None:
    """Per new frame: push (frame CNN once + transformer over the ring), and its parts."""
    spec = MODELS["cnn_transformer"]
    model = spec.build(N_CLASSES, channels, grid, preset).eval()
    view = spec.view(preset)
    predictor = StreamingPredictor(model, view, backend="onnx" if variant == "onnx" else "torch",
                                   threads=THREADS)
    frames = np.random.default_rng(0).normal(size=(view.frames + 400, channels, *grid))
    frames = frames.astype(np.float32)
    for f in frames[: view.frames]:
        predictor.push(f)
    it = iter(frames[view.frames:])
    per_frame = timed(lambda: predictor.push(next(it)), budget_s=2.0, max_runs=399)
    one = frames[0][None]
    ring = np.random.default_rng(1).normal(size=(1, view.frames, predictor._ring.shape[1]))
    ring = ring.astype(np.float32)
    # the statistics head (full preset) also reads the window's frames
    window = np.ascontiguousarray(frames[:view.frames].transpose(1, 0, 2, 3)[None])
    feed = {"input": ring, **({"window": window} if predictor.keeps_frames else {})}
    head_args = (torch.from_numpy(ring),) + \
        ((torch.from_numpy(window),) if predictor.keeps_frames else ())
    if variant == "onnx":
        cnn_s, head_s = predictor._sessions
        cnn = timed(lambda: cnn_s.run(None, {"frame": one}))
        transformer = timed(lambda: head_s.run(None, feed))
    else:
        with torch.inference_mode():
            cnn = timed(lambda: model.frame_features(torch.from_numpy(one)))
            transformer = timed(lambda: model.classify_embeddings(*head_args))
    print(f"cnn_transformer {preset:5s} {variant:5s} {channels}x{grid[0]}x{grid[1]:<3d} "
          f"window {view.frames:2d}: per frame {ms(per_frame)} | frame CNN {ms(cnn)} | "
          f"transformer {ms(transformer)}", flush=True)


def bench_training(name: str, preset: str, channels: int, grid, steps: int = 3) -> None:
    spec = MODELS[name]
    model = spec.build(N_CLASSES, channels, grid, preset).train()
    defaults = spec.train_defaults(preset)
    batch = min(defaults.batch_size, 32)
    x = torch.randn(batch, *model.input_shape)
    y = torch.randint(0, N_CLASSES, (batch,))
    opt = {"adam": torch.optim.Adam, "adamw": torch.optim.AdamW, "sgd": torch.optim.SGD}[
        defaults.optimizer](model.parameters(), lr=defaults.lr)

    def step() -> None:
        opt.zero_grad()
        F.cross_entropy(model(x), y).backward()
        opt.step()

    times = timed(step, budget_s=3.0, min_runs=steps, max_runs=50)
    print(f"{name:16s} {preset:5s} {channels}x{grid[0]}x{grid[1]:<3d} batch {batch:3d}: "
          f"{batch / statistics.median(times):9.1f} samples/s "
          f"({statistics.median(times) * 1e3:.1f} ms/step)", flush=True)


def main(argv: list[str] | None = None) -> None:
    global THREADS
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny presets only")
    parser.add_argument("--no-onnx", action="store_true", help="skip onnxruntime latency")
    parser.add_argument("--threads", type=int, default=THREADS, help="torch/onnxruntime threads")
    args = parser.parse_args(argv)
    THREADS = args.threads
    torch.set_num_threads(THREADS)
    torch.manual_seed(0)
    presets = ["tiny"] if args.quick else ["tiny", "full"]
    print(f"torch {torch.__version__}, {THREADS} threads, load average "
          f"{os.getloadavg()[0]:.1f} (shared machine: compare rows, not absolutes)")
    print("\n== batch-1 inference: params, state-dict size, latency median p95 (ms), "
          "ONNX file size ==")
    for name, configs in CONFIGS.items():
        for preset in presets:
            for channels, grid in configs:
                bench_inference(name, preset, channels, grid, onnx=not args.no_onnx)
    print("\n== streaming CNN-Transformer (median p95 ms; goal <= 1.3 ms per prediction) ==")
    print("per frame = push of one new frame incl. its CNN and a prediction over the window")
    for preset in presets:
        for channels, grid in [(1, (8, 8)), (3, (6, 6)), (3, (11, 11))]:
            for variant in ("torch", "onnx"):
                bench_streaming(preset, channels, grid, variant)
    print("\n== training throughput (forward+backward+step) ==")
    for name, configs in CONFIGS.items():
        for preset in presets:
            channels, grid = configs[0]
            bench_training(name, preset, channels, grid)


if __name__ == "__main__":
    main()
