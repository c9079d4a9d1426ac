"""The package layout: no top-level module names a user's own files can shadow, the core library does
not depend on the jobs built on it, and every package folder is a package (setuptools' find)."""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import REPO_ROOT

PACKAGE = REPO_ROOT / "trumans"
CORE_SUBPACKAGES = ("ik", "model", "contacts", "refine", "track", "synth", "importers", "eval", "viz", "scenes")
JOBS = ("trumans.sample", "trumans.train", "trumans.augment")  # built on the core library, never under it
# the front doors: the one-call Python API and the console script sit above every job; nothing imports them
# (``trumans/__init__`` reaches the API lazily, on first use)
FRONT_DOORS = (PACKAGE / "api.py", PACKAGE / "cli.py", PACKAGE / "__main__.py")


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def _imported(path: Path, root: Path = REPO_ROOT) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``path`` (function-local ones included): for
    ``from X import a`` both X and X.a, since ``a`` may be a submodule; relative imports resolved
    against the file's package (its folder under ``root``)."""
    package = ".".join(path.relative_to(root).parent.parts)
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            out += [(node.lineno, base)] + [(node.lineno, f"{base}.{a.name}") for a in node.names]
    return out


def _offending(paths: list[Path], forbidden: tuple[str, ...]) -> list[str]:
    return [f"{p.relative_to(REPO_ROOT)}:{line}: {name}" for p in paths for line, name in _imported(p)
            if any(name == f or name.startswith(f + ".") for f in forbidden)]


def test_the_import_resolver_sees_absolute_relative_and_local_imports(tmp_path):
    pkg = tmp_path / "trumans" / "scenes"
    pkg.mkdir(parents=True)
    mod = pkg / "mod.py"
    mod.write_text("import trumans.sample.cli\nfrom .. import train\nfrom ..augment.core import x\n"
                   "def f():\n    from trumans import sample\n")
    names = {n for _, n in _imported(mod, tmp_path)}
    assert {"trumans.sample.cli", "trumans.train", "trumans.augment.core", "trumans.sample"} <= names


def test_core_library_does_not_import_the_jobs():
    core = [p for p in _modules() if (p.parent == PACKAGE and p not in FRONT_DOORS)
            or p.relative_to(PACKAGE).parts[0] in CORE_SUBPACKAGES]
    assert len(core) > 50 and any(p.parent.name == "track" for p in core)
    assert _offending(core, JOBS) == []


def test_nothing_imports_the_python_api():
    inside = [p for p in _modules() if p not in FRONT_DOORS and p != PACKAGE / "__init__.py"]
    assert _offending(inside, ("trumans.api",)) == []


def test_tracking_does_not_import_sampling():
    track = [p for p in _modules() if p.relative_to(PACKAGE).parts[0] == "track"]
    assert track and _offending(track, ("trumans.sample",)) == []


def test_every_package_folder_has_an_init():
    folders = {p.parent for p in _modules()}
    assert PACKAGE in folders and PACKAGE / "sample" in folders
    assert sorted(str(f.relative_to(REPO_ROOT)) for f in folders if not (f / "__init__.py").is_file()) == []


@pytest.fixture()
def users_folder(tmp_path):
    """A working folder holding a user's own scripts named like the project's jobs, each failing on import."""
    for name in ("train", "sample", "scenes", "augment"):
        (tmp_path / f"{name}.py").write_text(f"raise RuntimeError('the user\\'s own {name}.py was imported')\n")
    return tmp_path


def test_users_own_train_or_sample_py_is_not_imported(users_folder):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (str(REPO_ROOT), os.environ.get("PYTHONPATH")) if p))
    code = ("import trumans, trumans.sample.cli, trumans.train.cli, trumans.augment.cli, trumans.scenes\n"
            "print(trumans.sample.cli.__file__, trumans.train.cli.__file__, trumans.augment.cli.__file__, "
            "trumans.scenes.__file__)")
    runs = [subprocess.Popen([sys.executable, *argv], cwd=users_folder, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
            for argv in (["-m", "trumans", "--help"], ["-c", code])]
    (help_out, help_err), (out, err) = (r.communicate(timeout=300) for r in runs)
    assert runs[0].returncode == 0, help_err
    assert "usage: trumans" in help_out and "sample" in help_out and "train" in help_out
    assert runs[1].returncode == 0, err
    files = [Path(f).resolve() for f in out.split()]
    assert len(files) == 4 and all(f.is_relative_to(PACKAGE.resolve()) for f in files), files


def test_tests_import_no_other_test_module_and_no_private_project_name():
    """Shared fixtures live in tests/conftest.py, shared helpers in tests/helpers.py; a test that needs
    a private function of the project tests it through the public one (or the function is made public)."""
    tests = REPO_ROOT / "tests"
    bad = []
    for path in sorted(tests.rglob("*.py")):
        for line, name in _imported(path, tests):
            top, last = name.split(".")[0], name.rsplit(".", 1)[-1]
            if top.startswith("test_") or top == "conftest" or (top == "trumans" and last.startswith("_")
                                                                   and not last.startswith("__")):
                bad.append(f"{path.relative_to(REPO_ROOT)}:{line}: {name}")
    assert bad == []
