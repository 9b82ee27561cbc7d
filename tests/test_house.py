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


def unresolved_relative_imports(path: Path) -> list[str]:
    """Relative imports (lazy ones inside functions included) that name no module or package
    beside the importer: what a move into a package silently breaks until the line runs."""
    missing = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not (isinstance(node, ast.ImportFrom) and node.level > 0):
            continue
        base = path.parent
        for _ in range(node.level - 1):
            base = base.parent
        if node.module is None:
            names = [a.name for a in node.names if not a.name.startswith("__")]
            init = (base / "__init__.py").read_text(encoding="utf-8") if (base / "__init__.py").exists() else ""
            missing += [n for n in names if not ((base / f"{n}.py").exists() or (base / n).is_dir() or n in init)]
            continue
        first = node.module.split(".")[0]
        if not ((base / f"{first}.py").exists() or (base / first / "__init__.py").exists()):
            missing.append(f"line {node.lineno}: .{node.module}")
    return missing


@pytest.mark.parametrize("package", PACKAGES)
def test_every_relative_import_resolves(package):
    broken = {str(p.relative_to(ROOT)): m for p in modules(package) if (m := unresolved_relative_imports(p))}
    assert not broken


def test_a_broken_relative_import_is_found(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "piece.py").write_text("def f():\n    from .hazard import X\n")
    assert unresolved_relative_imports(pkg / "piece.py") == ["line 2: .hazard"]


def test_ci_runs_the_readme_test_command_and_every_realtime_module_exists():
    """CI runs the test command README.md names (its line in .ci/run is quoted there as it
    stands), and each module kept out of the parallel phase exists: a renamed timing test would
    otherwise run on both cores beside the heavy ones and be judged under their load."""
    from conftest import REALTIME_MODULES

    command = (ROOT / ".ci" / "run").read_text(encoding="utf-8").rstrip("\n").splitlines()[-1]
    assert "pytest" in command and f"`{command}`" in (ROOT / "README.md").read_text(encoding="utf-8")
    assert "-m 'not realtime'" in command and "-m realtime" in command
    missing = sorted(m for m in REALTIME_MODULES if not (ROOT / "tests" / f"{m}.py").is_file())
    assert not missing, missing
