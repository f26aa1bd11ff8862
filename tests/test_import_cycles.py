"""No import cycles in the core, between modules or between packages, counting imports
inside functions and under TYPE_CHECKING (grimp reads every import statement)."""

from __future__ import annotations

import grimp


def _cycles(adj: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one member (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []
    for root in adj:
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
    return found


def _graphs() -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    g = grimp.build_graph("tactile_studio", include_external_packages=False)
    modules = {m: set(g.find_modules_directly_imported_by(m)) for m in g.modules}
    packages: dict[str, set[str]] = {}
    for m, deps in modules.items():
        if m.count(".") < 1:
            continue
        a = m.split(".")[1]
        packages.setdefault(a, set()).update(
            d.split(".")[1] for d in deps if d.count(".") >= 1 and d.split(".")[1] != a)
    return modules, packages


def test_no_module_or_package_cycles():
    modules, packages = _graphs()
    assert _cycles(modules) == []
    assert _cycles(packages) == []
    assert "storage" in packages and "learn" in packages  # the graph saw the core


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []
