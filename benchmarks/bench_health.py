"""Sensor health figures on the simulated sensor: how long a check and a calibration take
(headless, speed 0), false alarms over seeds, recovered sensitivity and rms after
calibration, and the seconds per placed weight the wizards' estimates use
(``health/estimate.py``; ``--real-time`` also measures them at the simulator's real
time, what a bench takes: about 5 min). Everything printed is measured here."""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np


def _engine(**settings):
    from tactile_studio.acquisition.open_stream import open_stream
    from tactile_studio.plugins.simulated import SimulatedSensor
    dev = SimulatedSensor(speed=0, gesture="idle", **settings)
    engine = open_stream(dev)
    engine.start()
    return dev, engine


PLATE = (1000, 2000, 5000, 10000, 20000)


def per_placement(real_time: bool) -> None:
    """Seconds per placed weight of each kind, through the wizards' own HealthCheck: the
    wall time at speed 0, and (``real_time``) the device time at speed 1."""
    from tactile_studio.health.calibration import CalibrationSpec
    from tactile_studio.health.estimate import FULL_SPEED_S, REAL_TIME_S
    from tactile_studio.health.health_check import HealthCheck
    from tactile_studio.health.wellness import WellnessSpec

    kinds = {"plate": (CalibrationSpec("sim-0", PLATE, plate=True), 5),
             "taxel": (CalibrationSpec("sim-0", (20, 50, 100, 200, 500), ("B2", "E5")), 10),
             "spot": (WellnessSpec("sim-0", 200.0), 5)}
    for kind, (spec, n) in kinds.items():
        for speed in ((0.0, 1.0) if real_time else (0.0,)):
            t = time.perf_counter()
            run = HealthCheck("simulated", {"speed": speed, "gesture": "idle"}, spec,
                              auto=True).start()
            run.join()
            wall = time.perf_counter() - t
            if run.error:
                raise SystemExit(f"{kind}: {run.error}")
            if speed == 0:
                print(f"  {kind}: {n} placements at full speed {wall:.2f} s wall, "
                      f"{wall / n:.2f} s each (estimate.FULL_SPEED_S {FULL_SPEED_S[kind]})")
            else:
                device_s = run.engine.frames / run.engine.nominal_rate_hz
                print(f"  {kind}: {n} placements in real time {device_s:.1f} s, "
                      f"{(device_s - 3.0) / n:.1f} s each after the 3 s rest "
                      f"(estimate.REAL_TIME_S {REAL_TIME_S[kind]})")


def main(argv: list[str] | None = None) -> None:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--real-time", action="store_true",
                    help="also measure seconds per placement at real time (~5 min)")
    args = ap.parse_args(argv)
    os.environ["TACTILE_STUDIO_DATA_DIR"] = tempfile.mkdtemp(prefix="ts-bench-health-")
    print("seconds per placed weight (the wizards' estimates):")
    per_placement(args.real_time)
    from tactile_studio.health.bench import Bench, SimulatedPlacer
    from tactile_studio.health.calibration import CalibrationSpec, run_calibration
    from tactile_studio.health.wellness import WellnessSpec, run_wellness

    # the default simulator varies like real sensors (~10% overall): judged against the
    # nominal curve an uncalibrated healthy sensor can warn; calibrated first (the README's
    # flow), against its own calibration
    for calibrated in (False, True):
        times, false_alarms, ratios = [], 0, []
        for seed in range(40):
            if calibrated:
                dev, engine = _engine(seed=seed)
                run_calibration(engine, CalibrationSpec(dev.sensor_id(), PLATE, plate=True),
                                placer=SimulatedPlacer(dev))
                engine.stop()
            dev, engine = _engine(seed=seed)
            t = time.perf_counter()
            res = run_wellness(Bench(engine, SimulatedPlacer(dev)),
                               WellnessSpec(dev.sensor_id(), 200.0))
            times.append(time.perf_counter() - t)
            engine.stop()
            false_alarms += res["verdict"] != "pass"
            ratios += [s["ratio"] for s in res["spots"]]
        print(f"wellness check (5 spots, speed 0, "
              f"{'after a plate calibration' if calibrated else 'uncalibrated'}): median "
              f"{np.median(times):.2f} s wall, false alarms {false_alarms}/40 healthy seeds, "
              f"spot ratio {np.mean(ratios):.3f} +- {np.std(ratios):.3f}")

    for label, spec in (
            ("plate, 5 loads, 36 taxels", CalibrationSpec("", (1000, 2000, 5000, 10000, 20000),
                                                          plate=True)),
            ("per taxel, 5 loads, 6 taxels", CalibrationSpec(
                "", (20, 50, 100, 200, 500), ("B2", "B5", "E2", "E5", "A1", "C4")))):
        errs, rms, wall = [], [], []
        for seed in (1, 2, 3):
            dev, engine = _engine(seed=seed, sensitivity_spread=0.15)
            t = time.perf_counter()
            cal = run_calibration(engine, CalibrationSpec(dev.sensor_id(), spec.loads_g,
                                                          spec.taxels, spec.plate),
                                  placer=SimulatedPlacer(dev))
            wall.append(time.perf_counter() - t)
            engine.stop()
            truth = dev.true_sensitivity()
            errs += [abs(f["sensitivity"] / truth[f["index"]] - 1) * 100 for f in cal["fits"]]
            rms += [f["rms_pct"] for f in cal["fits"]]
        print(f"calibration ({label}), 3 seeds: {np.median(wall):.1f} s wall; sensitivity "
              f"error median {np.median(errs):.2f}%, max {np.max(errs):.2f}%; rms error "
              f"median {np.median(rms):.2f}%, max {np.max(rms):.2f}% of range")


if __name__ == "__main__":
    import sys
    main(sys.argv[1:])
