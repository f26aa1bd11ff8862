"""Sensor health figures on the simulated sensor: how long a check and a calibration take
(headless, speed 0), false alarms over seeds, recovered sensitivity and rms after
calibration. Everything printed is measured here."""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np


def _engine(**settings):
    from tactile_studio.devices.engine import AcquisitionEngine
    from tactile_studio.plugins.simulated import SimulatedSensor
    dev = SimulatedSensor(speed=0, gesture="idle", **settings)
    engine = AcquisitionEngine(dev)
    engine.start()
    return dev, engine


PLATE = (1000, 2000, 5000, 10000, 20000)


def main() -> None:
    os.environ["TACTILE_STUDIO_DATA_DIR"] = tempfile.mkdtemp(prefix="ts-bench-health-")
    from tactile_studio.health.bench import SimulatedPlacer
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
            res = run_wellness(engine, WellnessSpec(dev.sensor_id(), 200.0),
                               SimulatedPlacer(dev))
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
    main()
