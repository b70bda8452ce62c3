"""Figures of the package's layout, read from its source: what a change to the layout is held to.

Prints the modules at the package's top level, the largest modules, the import circles (function
local imports count: they are imports all the same), private names imported from another room
(subpackage), and the files that name a ``.partial`` output. Nothing is imported or run.

    python scripts/house_figures.py [--package pcdcodec] [--json]
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]


def modules(package: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file of the package."""
    out: dict[str, Path] = {}
    for path in sorted(package.rglob("*.py")):
        parts = list(path.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    """The absolute module an ``ImportFrom`` names."""
    if node.level == 0:
        return node.module or ""
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(mods: dict[str, Path]) -> dict[str, set[tuple[str, str | None]]]:
    """For each module, the (module, imported name or None) pairs it imports inside the
    package, at any depth of the file."""
    out: dict[str, set[tuple[str, str | None]]] = {}
    for name, path in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        found: set[tuple[str, str | None]] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                found.update((a.name, None) for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                target = _resolve(name, path.name == "__init__.py", node)
                for alias in node.names:
                    sub = f"{target}.{alias.name}"
                    found.add((sub, None) if sub in mods else (target, alias.name))
        out[name] = {(m, n) for m, n in found if m in mods and m != name}
    return out


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []
    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(groups)


def _room(module: str) -> str:
    """The room a module lives in: its subpackage, or itself for a top-level module."""
    return ".".join(module.split(".")[:2])


def figures(package: Path) -> dict[str, Any]:
    mods = modules(package)
    packages = {m for m, p in mods.items() if p.name == "__init__.py"}
    found = imports(mods)
    graph = {m: {t for t, _ in targets} for m, targets in found.items()}
    sizes = {m: len(p.read_text(encoding="utf-8").splitlines()) for m, p in mods.items()}
    private = sorted(
        f"{m} <- {t}.{n}"
        for m, targets in found.items()
        for t, n in targets
        if n is not None and n.startswith("_") and not n.startswith("__") and _room(m) != _room(t)
    )
    partial = sorted(
        str(p.relative_to(package.parent))
        for p in mods.values()
        if ".partial" in p.read_text(encoding="utf-8")
    )
    largest = sorted(sizes.items(), key=lambda kv: -kv[1])
    return {
        "modules": len(mods),
        "top_level_modules": sum(1 for m in mods if m.count(".") == 1 and m not in packages),
        "over_800": [m for m, n in largest if n > 800],
        "over_600": len([m for m, n in largest if n > 600]),
        "largest": [f"{m} {n}" for m, n in largest[:8]],
        "circles": circles(graph),
        "private_cross_imports": private,
        "files_naming_partial": partial,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--package", type=Path, default=REPO / "pcdcodec")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    result = figures(args.package.resolve())
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    for key, value in result.items():
        if isinstance(value, list):
            print(f"{key}: {len(value)}")
            for item in value:
                print(f"  {' <-> '.join(item) if isinstance(item, list) else item}")
        else:
            print(f"{key}: {value}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
