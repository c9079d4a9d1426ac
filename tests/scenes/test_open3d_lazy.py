"""open3d is imported when a scene query first needs it: the sampler, the trainer and the refine
filter import without it, and a scene query without it says what to install."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

BLOCK = """
import sys
class _Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] == 'open3d':
            raise ImportError('no module named open3d (blocked by the test)')
sys.meta_path.insert(0, _Block())
"""


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", BLOCK + code], cwd=ROOT, capture_output=True, text=True, timeout=300)


def test_jobs_import_without_open3d():
    r = _run("import trumans.sample.sampler, trumans.train.loop, trumans.refine.pipeline, trumans.cli\n"
             "assert 'open3d' not in sys.modules\nprint('imported')")
    assert r.returncode == 0, r.stderr
    assert "imported" in r.stdout


def test_scene_query_without_open3d_names_the_fix():
    r = _run("import trimesh\nfrom trumans.scenes.distance import SceneDistance\n"
             "SceneDistance({'box': trimesh.creation.box((1, 1, 1))})")
    assert r.returncode != 0
    assert "pip install open3d" in r.stderr and "libusb-1.0-0" in r.stderr
