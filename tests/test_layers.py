"""The layering holds in every Python file, tests included (import-linter sees only packages).

splitter_model at the bottom, splitter_msgs_py on it, splitter_bag on that;
splitter_sim, splitter_mpc and splitter_ik beside each other, each importing only
the layers below; splitter_bringup on them, splitter_tools on top. A package's tests
live with it and follow its rule; the top-level tests/ may import anything.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "splitter_ws" / "src"
LEVEL = {
    "splitter_model": 0,
    "splitter_msgs_py": 1,
    "splitter_bag": 2,
    "splitter_sim": 3,
    "splitter_mpc": 3,
    "splitter_ik": 3,
    "splitter_bringup": 4,
    "splitter_tools": 5,
}


def imported_packages(path: Path) -> list[tuple[int, str]]:
    """(line, top-level package) of every import statement in ``path``, nested ones too."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name.split(".")[0]) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.lineno, node.module.split(".")[0]))
    return out


def layer_violations() -> list[str]:
    bad = []
    for package, level in LEVEL.items():
        for path in sorted((SRC / package).rglob("*.py")):
            for line, imported in imported_packages(path):
                if imported in LEVEL and imported != package and LEVEL[imported] >= level:
                    bad.append(f"{path.relative_to(ROOT)}:{line} imports {imported}")
    return bad


def test_no_package_imports_its_own_layer_or_one_above() -> None:
    assert layer_violations() == []


def test_the_check_finds_an_upward_import(tmp_path, monkeypatch) -> None:
    fake = tmp_path / "splitter_ws" / "src"
    (fake / "splitter_sim" / "test").mkdir(parents=True)
    (fake / "splitter_sim" / "test" / "test_x.py").write_text(
        "def f():\n    from splitter_bringup.scenario import definition as scenario\n"
    )
    (fake / "splitter_model").mkdir()
    (fake / "splitter_model" / "m.py").write_text("import splitter_model.model\n")
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    monkeypatch.setitem(globals(), "SRC", fake)
    assert layer_violations() == [
        "splitter_ws/src/splitter_sim/test/test_x.py:2 imports splitter_bringup"
    ]
