"""The all-taxel characterisation on the simulated bench at speed=0 (target: < 2 min wall).

Runs ``characterise --taxels all --sequence normal`` then ``--sequence shear`` equivalents
in one run (the paper's default plan: 16+16 normal steps, 10 shear steps in 4 directions,
3 s dwells), prints wall time, simulated time and how far off the simulator's truth
the worst taxel is, per parameter.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

from tactile_studio.characterise import CharacterisationRequest, Plan, run_characterisation
from tactile_studio.devices.registry import create_device
from tactile_studio.plugins.sim_force import SimulatedForce
from tactile_studio.plugins.sim_stage import SimulatedStage
from tactile_studio.sensor.characterise import parse_taxels
from tactile_studio.simulate.indenter import true_parameters

KEYS = ("normal_sensitivity_low", "normal_sensitivity_high", "breakpoint_kpa",
        "shear_sensitivity_x", "shear_sensitivity_y", "crosstalk_max", "relaxation_s",
        "shear_offset")


def main() -> None:
    dev = create_device("simulated", {"speed": 0, "gesture": "idle"})
    stage, force = SimulatedStage(), SimulatedForce()
    taxels = parse_taxels(dev.layout, "all")
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        result = run_characterisation(dev, stage, force, CharacterisationRequest(
            Plan(sequences=("normal", "shear")), taxels, Path(tmp), report=False))
        run_s = time.perf_counter() - start
        from tactile_studio.characterise.report import write_report

        t0 = time.perf_counter()
        raw = {p.stem: json.loads(p.read_text()) for p in (Path(tmp) / "raw").glob("*.json")}
        figures = write_report(Path(tmp), result, dev.layout, raw)
        report_s = time.perf_counter() - t0
        size = (Path(tmp) / "session.h5").stat().st_size
    sim_s = dev.simulator.frame / dev.simulator.rate
    print(f"all {len(taxels)} taxels, normal+shear: {run_s:.1f} s wall for {sim_s:.0f} s of "
          f"simulated lab time ({sim_s / run_s:.0f}x real time); report {report_s:.1f} s "
          f"({len(figures)} files); session {size / 1e6:.0f} MB")
    print(f"total {run_s + report_s:.1f} s wall (target < 120 s)")
    worst = {k: 0.0 for k in KEYS}
    for t in taxels:
        name = dev.layout.taxel_name(*dev.layout.taxel_rc(t))
        truth = true_parameters(dev.simulator, stage.skin, t)
        for k in KEYS:
            worst[k] = max(worst[k], abs(result["taxels"][name][k] / truth[k] - 1))
    for k, v in worst.items():
        print(f"  worst taxel error {k:<24} {v * 100:5.1f} %")


if __name__ == "__main__":
    main()
