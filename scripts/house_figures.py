"""Figures of the package's layout, read from its source: what a change to the layout is held to.

Prints the modules at the package's top level (its entry files ``__init__``, ``__main__`` and
``_version`` are not rooms and do not count), the largest modules, the import circles (function
local and ``TYPE_CHECKING`` imports count: they are imports all the same), private names imported
from another room (subpackage), the files that name a ``.partial`` output, and the pairs of
modules that repeat a run of six or more lines to the letter (blank, comment and import lines
aside). Nothing is imported or run.

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


def local_imports(mods: dict[str, Path]) -> int:
    """How many import statements inside functions name a module of the package (lazy imports of
    heavy libraries are not counted: they are imports of other packages)."""
    count = 0
    for name, path in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        seen: set[int] = set()  # a nested function's imports are walked from its parent too
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if id(node) in seen:
                    continue
                seen.add(id(node))
                if isinstance(node, ast.ImportFrom):
                    target = _resolve(name, path.name == "__init__.py", node)
                    count += any(target == m or target.startswith(m + ".") for m in mods)
                elif isinstance(node, ast.Import):
                    count += any(a.name in mods for a in node.names)
    return count


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


#: Files of the package that are its entry points rather than rooms.
ENTRY_FILES = {"__main__", "_version"}
#: How many lines two places must share, in a row, to count as repeated code.
REPEAT_LINES = 6
#: A run found in more places than this is boilerplate, not a repetition worth a row.
REPEAT_PLACES = 8


def _code_lines(path: Path) -> list[tuple[int, str]]:
    """(line number, text with white space folded) of the lines that carry code."""
    out = []
    for number, raw in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        line = " ".join(raw.split())
        if not line or line.startswith("#") or line.startswith(("import ", "from ")):
            continue
        if all(c in "()[]{},:;" for c in line):
            continue
        out.append((number, line))
    return out


def repeated_code(mods: dict[str, Path]) -> list[str]:
    """``a.py:10 ~ b.py:40`` for each pair of places (a module with itself or with another) that
    share a run of :data:`REPEAT_LINES` identical code lines; one row per pair of modules and
    stretch of lines, the longest run of each."""
    lines = {m: _code_lines(p) for m, p in mods.items()}
    places: dict[tuple[str, ...], list[tuple[str, int]]] = {}
    for m, code in lines.items():
        for i in range(len(code) - REPEAT_LINES + 1):
            key = tuple(text for _, text in code[i : i + REPEAT_LINES])
            places.setdefault(key, []).append((m, i))
    # pairs of windows, grouped by diagonal so that overlapping windows make one run
    diagonals: dict[tuple[str, str, int], list[int]] = {}
    for found in places.values():
        if len(found) < 2 or len(found) > REPEAT_PLACES:
            continue
        for a in range(len(found)):
            for b in range(a + 1, len(found)):
                (ma, ia), (mb, ib) = sorted((found[a], found[b]))
                if ma == mb and abs(ia - ib) < REPEAT_LINES:
                    continue  # a run overlapping itself
                diagonals.setdefault((ma, mb, ib - ia), []).append(ia)
    rows = []
    for (ma, mb, offset), starts in sorted(diagonals.items()):
        starts.sort()
        runs = [[starts[0], starts[0]]]
        for s in starts[1:]:
            if s == runs[-1][1] + 1:
                runs[-1][1] = s
            else:
                runs.append([s, s])
        for first, last in runs:
            la = lines[ma][first][0]
            lb = lines[mb][first + offset][0]
            rows.append(f"{ma}:{la} ~ {mb}:{lb} ({last - first + REPEAT_LINES} lines)")
    return rows


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
        "top_level_modules": sorted(
            m
            for m in mods
            if m.count(".") == 1 and m not in packages and m.split(".")[1] not in ENTRY_FILES
        ),
        "over_800": [m for m, n in largest if n > 800],
        "over_600": len([m for m, n in largest if n > 600]),
        "largest": [f"{m} {n}" for m, n in largest[:8]],
        "circles": circles(graph),
        "function_local_imports": local_imports(mods),
        "private_cross_imports": private,
        "files_naming_partial": partial,
        "repeated_code": repeated_code(mods),
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
