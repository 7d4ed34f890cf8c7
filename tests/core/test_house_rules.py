"""The house rules as tests: module size, one opening line, a core without Blender, the layers' imports, the test lanes."""

import ast
import collections
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "prt_addon"
MAX_LINES = 400
BLENDER_MODULES = ("bpy", "bpy_extras", "bmesh", "mathutils", "gpu", "gpu_extras", "addon_utils")
# Which top-level groups of prt_addon.blender each group may import (besides the core, which
# every group may import, and caches.py, which imports nothing of the add-on).
ALLOWED = {
    "world": set(),
    "scene": {"world", "display.redraw"},
    "bake": {"world", "scene"},
    "display": {"world", "scene"},
    "export": {"world", "scene"},
}


def _sources(*folders, suffixes=(".py",)):
    for folder in folders:
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix in suffixes and ".venv" not in path.parts and "node_modules" not in path.parts:
                yield path


def _module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path):
    """Absolute names of every module `path` imports (relative imports resolved)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    here = _module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package[: len(package) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                yield f"{base}.{alias.name}" if base else alias.name, node.lineno


def test_no_module_is_over_400_lines():
    long = [
        (str(p.relative_to(ROOT)), n)
        for p in _sources(
            "prt_addon",
            "tests",
            "benchmarks",
            "scripts",
            "examples",
            "web/src",
            "web/tools",
            suffixes=(".py", ".js", ".mjs"),
        )
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    ]
    assert not long, f"modules over {MAX_LINES} lines: {long}"


def test_each_module_opens_with_one_line_that_says_what_it_holds():
    missing = []
    for path in _sources("prt_addon"):
        tree = ast.parse(path.read_text())
        doc = ast.get_docstring(tree, clean=False)
        first = path.read_text().splitlines()[0] if path.read_text() else ""
        if not doc or not doc.splitlines()[0].strip() or not first.startswith('"""'):
            missing.append(str(path.relative_to(ROOT)))
    assert not missing, f"modules without an opening docstring line: {missing}"


def test_the_core_imports_no_blender_module():
    found = [
        (str(p.relative_to(ROOT)), line, name)
        for p in _sources("prt_addon/core")
        for name, line in _imports(p)
        if name.split(".")[0] in BLENDER_MODULES
    ]
    assert not found, found


@pytest.mark.parametrize("group", sorted(ALLOWED))
def test_blender_layer_groups_import_only_what_the_map_allows(group):
    wrong = []
    for path in _sources(f"prt_addon/blender/{group}"):
        for name, line in _imports(path):
            if not name.startswith("prt_addon.blender."):
                continue
            rest = name[len("prt_addon.blender.") :]
            target = rest.split(".")[0]
            if target in (group, "caches") or any(rest == a or rest.startswith(a + ".") for a in ALLOWED[group]):
                continue
            wrong.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert not wrong, wrong


def test_no_reexport_shims():
    """Callers import from where the code lives: no import kept only for other modules."""
    shims = [
        f"{p.relative_to(ROOT)}:{i + 1}"
        for p in _sources("prt_addon")
        for i, line in enumerate(p.read_text().splitlines())
        if "noqa: F401" in line and "import numpy" not in line
    ]
    assert not shims, shims


TESTS = ROOT / "tests"
# The lane folders and the markers each gives (tests/conftest.py, LANES).
LANE_MARKS = {
    "core": (),
    "blender": ("blender",),
    "cycles": ("blender", "cycles"),
    "gpu": ("blender", "gpu"),
    "browser": ("blender", "browser"),
}
# An import of a test module or of a conftest, as code or as the text of code run in a subprocess.
TEST_MODULE_IMPORT = re.compile(r"^\s*(?:from|import)\s+(?:[\w.]*\.)?(?:test_\w+|conftest)\b", re.M)


def _test_modules():
    return sorted(p for p in TESTS.rglob("test_*.py") if "node_modules" not in p.parts)


def test_no_test_module_imports_another():
    """Shared code lives in tests/helpers/ (fixtures through pytest_plugins): a test module that
    imports another works only under one import mode and drags in its fixtures by name."""
    found = [
        f"{p.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}: {m.group(0).strip()}"
        for p in sorted(TESTS.rglob("*.py"))
        for text in [p.read_text()]
        for m in TEST_MODULE_IMPORT.finditer(text)
    ]
    assert not found, found


def test_each_test_module_is_in_a_lane_folder_under_a_unique_name():
    """tests/<lane>/test_*.py only (the folder gives the markers), and no two with the same file
    name: pytest's default import mode imports each as a top-level module of that name."""
    outside = [
        str(p.relative_to(ROOT)) for p in _test_modules() if p.parent.parent != TESTS or p.parent.name not in LANE_MARKS
    ]
    assert not outside, f"test modules outside tests/{{{','.join(LANE_MARKS)}}}/: {outside}"
    names = collections.Counter(p.name for p in _test_modules())
    assert not [n for n, c in names.items() if c > 1], names.most_common(3)


def test_no_lane_marker_that_the_folder_gives_is_written_by_hand():
    written = [
        f"{p.relative_to(ROOT)}:{i + 1}"
        for p in _test_modules()
        if p.parent.name in LANE_MARKS
        for i, line in enumerate(p.read_text().splitlines())
        for mark in LANE_MARKS[p.parent.name]
        if f"pytest.mark.{mark}" in line
    ]
    assert not written, written


def test_these_rules_see_a_breach():
    """The checks above find what they look for (a rule that cannot fail is no rule)."""
    sample = ROOT / "prt_addon" / "core" / "sh" / "basis.py"
    assert any(name == "numpy" for name, _ in _imports(sample))
    relative = ROOT / "prt_addon" / "blender" / "scene" / "lighting.py"
    names = {name for name, _ in _imports(relative)}
    assert "prt_addon.blender.display.redraw.tag_redraw" in names  # relative imports resolved
    breaches = (
        "from test_display import add_camera\n    from tests.core.test_raytrace import wavy_grid\nimport conftest\n"
    )
    assert len(TEST_MODULE_IMPORT.findall(breaches)) == 3
    assert not TEST_MODULE_IMPORT.findall("from helpers.worlds import new_world\nimport pytest\n")
