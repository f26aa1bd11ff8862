"""docs/instruments.md cannot rot: its `# file:` blocks are written out as a package; its
entry points, installed as a dist-info on the path as pip leaves them, are found by the
stage and force registries in a fresh process and drive the package's emulators; the
package's own tests (check_stage, check_force, soft limits, faults) pass under pytest."""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

from tactile_studio.instruments import ForcePlugin, StagePlugin

DOC = Path(__file__).resolve().parents[1] / "docs" / "instruments.md"
BLOCK = re.compile(r"```(?:python|toml)\n# file: (\S+)\n(.*?)```", re.S)
GROUPS = {"tactile_studio.stages": StagePlugin, "tactile_studio.forces": ForcePlugin}


def doc_files() -> dict[str, str]:
    return {name: body for name, body in BLOCK.findall(DOC.read_text(encoding="utf-8"))}


def write_package(root: Path) -> dict:
    for name, body in doc_files().items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(body, encoding="utf-8")
    return tomllib.loads((root / "pyproject.toml").read_text())["project"]


def install_entry_points(root: Path, meta: dict) -> Path:
    """What ``pip install`` leaves for importlib.metadata: a dist-info with the pyproject's
    entry points, in a folder put on the path."""
    info = root / "site" / f"{meta['name'].replace('-', '_')}-{meta['version']}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {meta['name']}\n"
                                   f"Version: {meta['version']}\n")
    lines = []
    for group, eps in meta["entry-points"].items():
        lines.append(f"[{group}]")
        lines += [f"{name} = {target}" for name, target in eps.items()]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return root / "site"


def _env(*paths: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [*map(str, paths), *filter(None, [os.environ.get("PYTHONPATH")])])}


def test_the_doc_holds_a_whole_package():
    assert set(doc_files()) == {"pyproject.toml", "src/tactile_bench/__init__.py",
                                "src/tactile_bench/stage.py", "src/tactile_bench/force.py",
                                "src/tactile_bench/emulators.py", "tests/test_bench.py"}


def test_entry_points_name_plugin_classes_of_the_same_name(tmp_path, monkeypatch):
    meta = write_package(tmp_path)
    assert {g: set(eps) for g, eps in meta["entry-points"].items()} == {
        "tactile_studio.stages": {"flexure"}, "tactile_studio.forces": {"bench-cell"}}
    monkeypatch.syspath_prepend(str(tmp_path / "src"))
    for mod in [m for m in sys.modules if m == "tactile_bench" or m.startswith("tactile_bench.")]:
        monkeypatch.delitem(sys.modules, mod)
    for group, eps in meta["entry-points"].items():
        for name, target in eps.items():
            module, _, attr = target.partition(":")
            cls = getattr(importlib.import_module(module), attr)
            assert issubclass(cls, GROUPS[group]) and cls.name == name


REGISTRY_ROUTE = """
from tactile_bench.emulators import CellEmulator, StageEmulator
from tactile_studio.instruments import available, create_force, create_stage
from tactile_studio.instruments.registry import FORCE_GROUP, STAGE_GROUP

assert available(STAGE_GROUP)["flexure"].__name__ == "FlexureStage", available(STAGE_GROUP)
assert available(FORCE_GROUP)["bench-cell"].__name__ == "BenchCell", available(FORCE_GROUP)
stage_emulator, cell_emulator = StageEmulator(), CellEmulator(force=(0.0, 0.0, 1.5))
stage_emulator.open(); cell_emulator.open()
stage = create_stage("flexure", {"port": stage_emulator.port, "floor_z": "-0.5"})
cell = create_force("bench-cell", {"port": cell_emulator.port})
stage.open(); cell.open()
stage.home()
stage.move_to(x=2.0, z=-0.25, speed=20.0)
stage.wait_until_still(10.0)
print("position", stage.position())
samples = cell.read()
while not len(samples):
    samples = cell.read()
print("force", samples.f[-1].tolist())
stage.close(); cell.close(); stage_emulator.stop(); cell_emulator.stop()
"""


def test_installed_entry_points_are_found_by_the_registries(tmp_path):
    site = install_entry_points(tmp_path, write_package(tmp_path))
    proc = subprocess.run([sys.executable, "-c", REGISTRY_ROUTE], cwd=tmp_path,
                          env=_env(site, tmp_path / "src"), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "position (2.0, 0.0, -0.25)" in proc.stdout
    assert "force [0.0, 0.0, 1.5]" in proc.stdout
    # the CLI's options name them too: a port nothing answers on is one line, exit 1
    proc = subprocess.run(
        [sys.executable, "-m", "tactile_studio", "characterise", "--stage", "flexure",
         "--stage-set", f"port={tmp_path / 'no-such-port'}", "--force", "bench-cell",
         "--force-set", f"port={tmp_path / 'no-such-port'}", "--out", str(tmp_path / "out")],
        cwd=tmp_path, env=_env(site, tmp_path / "src"), capture_output=True, text=True,
        timeout=120)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert re.fullmatch(r"tactile-studio: error: (stage flexure|force bench-cell): cannot "
                        r"open \S*no-such-port \(.*\)", proc.stderr.strip()), proc.stderr


def test_the_packages_own_tests_pass(tmp_path):
    write_package(tmp_path)
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--rootdir",
         str(tmp_path), str(tmp_path / "tests")],
        cwd=tmp_path, env=_env(tmp_path / "src"), capture_output=True, text=True,
        timeout=180)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "6 passed" in proc.stdout
