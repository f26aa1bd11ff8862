"""The whole house under the import guards: `make lint` runs this, the tests call it.

ui/, plugins/ and resources/ are installed as tactile_studio.ui, .plugins and .resources
(pyproject.toml's package-dir), but they sit beside tactile_studio/, so import-linter and
grimp, which scan the package's folder, would see only the core. Here a copy of the tree
is built with the three placed inside tactile_studio/ (the layout as Python imports it),
and on that copy the contracts of pyproject.toml [tool.importlinter] are checked and every
import cycle is looked for (between modules, and between top-level packages), counting
imports inside functions and under TYPE_CHECKING.

    python tools/house_imports.py           # contracts and cycles; exit 1 on any break
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PLACED = ("ui", "plugins", "resources")  # folders mapped into the namespace by package-dir
_IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc")
LINT = Path(sys.executable).parent / "lint-imports"


def build_house(dest: Path, root: Path = ROOT) -> Path:
    """A copy of the product code at ``dest`` as Python sees it: ``dest/tactile_studio``
    with ui/, plugins/ and resources/ inside, and pyproject.toml beside it."""
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copytree(root / "tactile_studio", dest / "tactile_studio", ignore=_IGNORE)
    for folder in PLACED:
        shutil.copytree(root / folder, dest / "tactile_studio" / folder, ignore=_IGNORE)
    shutil.copy(root / "pyproject.toml", dest / "pyproject.toml")
    return dest


def _env(house: Path) -> dict[str, str]:
    # the copy, not the installed tree, is what `import tactile_studio` finds
    return {**os.environ, "PYTHONPATH": str(house)}


def lint(house: Path) -> subprocess.CompletedProcess:
    """import-linter's contracts on ``house``; returncode 0 when every one is kept."""
    return subprocess.run([str(LINT), "--no-cache", "--no-logo", str(house / "pyproject.toml")],
                          cwd=house, env=_env(house), capture_output=True, text=True,
                          timeout=240)


def cycles_of(adj: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one member (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []
    for root in sorted(adj):
        if root in index:
            continue
        work = [(root, iter(sorted(adj.get(root, ()))))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(adj.get(w, ())))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
    return sorted(found)


def _graphs_here() -> dict[str, dict[str, list[str]]]:
    """The module and top-level package import graphs of the tactile_studio on sys.path."""
    import grimp

    g = grimp.build_graph("tactile_studio", include_external_packages=False, cache_dir=None)
    modules = {m: sorted(g.find_modules_directly_imported_by(m)) for m in g.modules}
    packages: dict[str, set[str]] = {}
    for m, deps in modules.items():
        if m.count(".") < 1:
            continue
        a = m.split(".")[1]
        packages.setdefault(a, set()).update(
            d.split(".")[1] for d in deps if d.count(".") >= 1 and d.split(".")[1] != a)
    return {"modules": modules, "packages": {k: sorted(v) for k, v in packages.items()}}


def graphs(house: Path) -> dict[str, dict[str, set[str]]]:
    """The import graphs of ``house`` (read in a child process: this one may already have
    imported the installed tactile_studio)."""
    out = subprocess.run([sys.executable, __file__, "--graphs"], cwd=house, env=_env(house),
                         capture_output=True, text=True, timeout=240, check=True).stdout
    raw = json.loads(out)
    return {kind: {k: set(v) for k, v in adj.items()} for kind, adj in raw.items()}


def cycles(house: Path) -> dict[str, list[list[str]]]:
    """Every import circle in ``house``: {"modules": [...], "packages": [...]}."""
    return {kind: cycles_of(adj) for kind, adj in graphs(house).items()}


def main() -> int:
    if sys.argv[1:] == ["--graphs"]:
        sys.path.insert(0, os.getcwd())
        print(json.dumps(_graphs_here()))
        return 0
    with tempfile.TemporaryDirectory(prefix="tactile-house-") as tmp:
        house = build_house(Path(tmp))
        result = lint(house)
        print(result.stdout.strip(), result.stderr.strip(), sep="\n")
        found = cycles(house)
        for kind, circles in found.items():
            for circle in circles:
                print(f"import cycle between {kind}: {' <-> '.join(circle)}")
        if not any(found.values()):
            print("No import cycles between modules or packages.")
        return 1 if result.returncode != 0 or any(found.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
