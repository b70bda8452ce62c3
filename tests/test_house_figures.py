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
    assert figures["top_level_modules"] == 2
    assert figures["circles"] == [["pkg.a", "pkg.b"]]
    assert figures["private_cross_imports"] == ["pkg.b <- pkg.room.c._private"]
    assert figures["over_800"] == ["pkg.room.c"]
    assert figures["files_naming_partial"] == ["pkg/room/d.py"]


def test_the_package_itself_is_read() -> None:
    figures = _script().figures(REPO / "pcdcodec")
    assert figures["modules"] > 40
    assert figures["top_level_modules"] > 0
    assert all(m.startswith("pcdcodec.") for m in figures["over_800"])
