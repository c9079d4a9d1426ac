"""trumans.scenes.atomic.atomic_write (re-exported by trumans.sequence) and the scenes -> trumans direction."""
from pathlib import Path

import pytest

from trumans.scenes.atomic import atomic_write

from helpers import REPO_ROOT


def test_atomic_write_replaces_or_leaves_nothing(tmp_path):
    p = tmp_path / "sub" / "a.txt"
    atomic_write(p, lambda tmp: Path(tmp).write_text("one"))
    assert p.read_text() == "one"

    def broken(tmp):
        Path(tmp).write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(p, broken)
    assert p.read_text() == "one"  # the old file is untouched
    assert [f.name for f in p.parent.iterdir()] == ["a.txt"]  # no temporary file left


def test_trumans_sequence_reuses_it():
    from trumans.sequence import atomic_write as seq_atomic_write

    assert seq_atomic_write is atomic_write


def test_scenes_never_imports_trumans():
    """No import of trumans anywhere in scenes/, lazy ones inside functions included."""
    import ast

    root = REPO_ROOT / "scenes"
    bad = []
    for f in sorted(root.glob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else []
            bad += [f"{f.name}:{node.lineno} {n}" for n in names if n == "trumans" or n.startswith("trumans.")]
    assert not bad, bad
