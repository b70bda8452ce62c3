"""scripts/house_figures.py on a small package made for the test."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[1]


def _script() -> ModuleType:
    path = REPO / "scripts" / "house_figures.py"
    spec = importlib.util.spec_from_file_location("house_figures", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["house_figures"] = module
    spec.loader.exec_module(module)
    return module


def test_figures_of_a_small_package(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    (pkg / "room").mkdir(parents=True)
    files = {
        "__init__.py": "from .a import thing\n",
        "a.py": "def thing():\n    from .b import other  # a function-local import is one too\n",
        "b.py": "from .a import thing\nfrom .room.c import _private\n",
        "room/__init__.py": "",
        "room/c.py": "def _private():\n    pass\n" + "x = 1\n" * 900,
        "room/d.py": "from .c import _private  # the same room: allowed\nNAME = '.out.partial-1'\n",
    }
    for name, text in files.items():
        (pkg / name).write_text(text)
    figures = _script().figures(pkg)
    assert figures["modules"] == 6
    assert figures["top_level_modules"] == ["pkg.a", "pkg.b"]
    assert figures["circles"] == [["pkg.a", "pkg.b"]]
    assert figures["private_cross_imports"] == ["pkg.b <- pkg.room.c._private"]
    assert figures["over_800"] == ["pkg.room.c"]
    assert figures["files_naming_partial"] == ["pkg/room/d.py"]


def test_the_package_itself_is_read() -> None:
    figures = _script().figures(REPO / "pcdcodec")
    assert figures["modules"] > 40
    assert "pcdcodec.errors" in figures["top_level_modules"]
    assert "pcdcodec._version" not in figures["top_level_modules"]
    assert all(m.startswith("pcdcodec.") for m in figures["over_800"])


def test_repeated_code_and_local_imports(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    body = "".join(f"    total = total + {i} * value\n" for i in range(7))
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(f"def f(value):\n    total = 0\n{body}    return total\n")
    (pkg / "b.py").write_text(
        "import os\n\n\ndef g(value):\n    from .a import f\n    import json\n"
        f"    total = 1\n{body}    return f(total)\n"
    )
    (pkg / "c.py").write_text("def h(value):\n" + "".join(f"    x{i} = {i}\n" for i in range(5)))
    figures = _script().figures(pkg)
    # the seven shared lines make one row, however many 6-line windows they hold
    assert figures["repeated_code"] == ["pkg.a:3 ~ pkg.b:8 (7 lines)"]
    # `from .a import f` inside g counts; `import json` (another package) and `import os` do not
    assert figures["function_local_imports"] == 1


#: The rooms in the order docs/architecture.md gives: each imports only rooms on lines above.
ROOM_ORDER = [
    ["errors", "_progress", "_version"],
    ["_atomic", "_validate", "codec", "sync"],
    ["registry", "geometry", "metrics"],
    ["frame", "depth", "color"],
    ["ros"],
    ["sources"],
    ["datasets", "recording"],
    ["convert", "viewer", "archive", "bench", "zarr", "torch"],
    ["cli", "testing"],
    ["__main__"],
]


def test_rooms_import_only_the_rooms_above_them() -> None:
    hf = _script()
    mods = hf.modules(REPO / "pcdcodec")
    level = {room: i for i, rooms in enumerate(ROOM_ORDER) for room in rooms}
    wrong = []
    for module, targets in hf.imports(mods).items():
        room = hf._room(module).removeprefix("pcdcodec").lstrip(".")
        if not room:
            continue  # pcdcodec/__init__.py gathers the public API from every room
        assert room in level, f"{room} is not placed in ROOM_ORDER (and docs/architecture.md)"
        for target, _ in targets:
            other = hf._room(target).removeprefix("pcdcodec").lstrip(".")
            if other and other != room and level[other] >= level[room]:
                wrong.append(f"{module} imports {target}")
    assert wrong == []


def test_the_layout_keeps_its_figures() -> None:
    figures = _script().figures(REPO / "pcdcodec")
    assert len(figures["top_level_modules"]) <= 12
    assert figures["over_800"] == []
    assert figures["over_600"] <= 4
    assert figures["circles"] == []
    assert figures["private_cross_imports"] == []
    assert len(figures["files_naming_partial"]) <= 2
