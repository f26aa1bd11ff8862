"""docs/plugins.md cannot rot: its `# file:` blocks are written out as a package, the
entry points resolve to plugin classes of the same name, and the package's own tests
(which call check_plugin) pass under pytest."""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

from tactile_studio.devices import DevicePlugin, check_plugin

DOC = Path(__file__).resolve().parents[1] / "docs" / "plugins.md"
BLOCK = re.compile(r"```(?:python|toml)\n# file: (\S+)\n(.*?)```", re.S)


def doc_files() -> dict[str, str]:
    return {name: body for name, body in BLOCK.findall(DOC.read_text())}


def write_package(root: Path) -> dict[str, str]:
    files = doc_files()
    for name, body in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(body)
    return files


def test_the_doc_holds_a_whole_package():
    assert set(doc_files()) == {"pyproject.toml", "src/tactile_mat/__init__.py",
                                "src/tactile_mat/device.py", "src/tactile_mat/discovering.py",
                                "tests/test_device.py"}


def test_entry_points_resolve_to_plugins_that_pass_the_static_checks(tmp_path, monkeypatch):
    write_package(tmp_path)
    meta = tomllib.loads((tmp_path / "pyproject.toml").read_text())
    eps = meta["project"]["entry-points"]["tactile_studio.devices"]
    assert set(eps) == {"mat", "mat-scan"}
    monkeypatch.syspath_prepend(str(tmp_path / "src"))
    for mod in [m for m in sys.modules if m == "tactile_mat" or m.startswith("tactile_mat.")]:
        monkeypatch.delitem(sys.modules, mod)
    for name, target in eps.items():
        module, _, attr = target.partition(":")
        cls = getattr(importlib.import_module(module), attr)
        assert issubclass(cls, DevicePlugin) and cls.name == name
        # nothing listens on this port: the static checks pass, only open() is reported
        try:
            check_plugin(cls, {"port": 9, "rows": 2, "cols": 2}, timeout_s=1)
        except AssertionError as exc:
            assert [p for p in exc.problems if "open() raised DeviceNotFound" not in p] == []


def test_the_packages_own_tests_pass(tmp_path):
    write_package(tmp_path)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(tmp_path / "src"), *filter(None, [os.environ.get("PYTHONPATH")])])}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--rootdir",
         str(tmp_path), str(tmp_path / "tests")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "3 passed" in proc.stdout
