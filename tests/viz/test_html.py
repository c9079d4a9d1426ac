"""`trumans view --html`: the self-contained three.js viewer, built here and run in headless Chromium."""
import base64
import html as htmllib
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
import trimesh

from trumans.actions import ActionInterval, labels_from_intervals
from trumans.cli import main as cli_main
from trumans.sequence import ObjectTrack, Sequence, save_sequence
from trumans.skeleton import JOINT_NAMES, REST_JOINTS
from trumans.viz import SceneView
from trumans.viz.html import THREE_MODULES, action_segments, three_import_map, write_html

CHROMIUM = next((p for p in (shutil.which(n) for n in ("chromium", "chromium-browser")) if p), None)
VENDOR = Path(__file__).resolve().parents[2] / "trumans" / "viz" / "vendor" / "three"
FPS, T = 30.0, 61  # a 2 s clip
VOCAB = ["stand", "walk", "sit"]


def walking(start_y: float = 0.0, goals: bool = True) -> Sequence:
    """Stand 0.67 s, then walk 1.5 m along +x; the left foot in contact for 1 s, then the right wrist."""
    x = np.concatenate([np.zeros(20), np.linspace(0.0, 1.5, T - 20)])
    joints = REST_JOINTS[None] + (x[:, None] * [1.0, 0.0, 0.0] + [-0.75, start_y, 0.0])[:, None, :]
    acts = labels_from_intervals([ActionInterval("stand", 0, 20), ActionInterval("walk", 20, T)], VOCAB, T)
    contacts = np.zeros((T, 24), bool)
    contacts[:30, JOINT_NAMES.index("left_foot")] = True
    contacts[30:, JOINT_NAMES.index("right_wrist")] = True
    extra = {"goals": np.array([[T - 1, 0.75, start_y, 0.9]])} if goals else {}
    return Sequence(joints=joints, fps=FPS, actions=acts, action_names=VOCAB, contacts=contacts, extra=extra)


def room_mesh() -> trimesh.Trimesh:
    """A 4 x 3 m floor slab (top at z = 0) and a 1 m high block behind the walk."""
    floor = trimesh.creation.box((4.0, 3.0, 0.05))
    floor.apply_translation([0.0, 0.0, -0.025])
    block = trimesh.creation.box((0.6, 0.6, 1.0))
    block.apply_translation([0.0, 1.0, 0.5])
    return trimesh.util.concatenate([floor, block])


# ---- pure parts ---------------------------------------------------------------------------------------------


def test_action_segments():
    acts = labels_from_intervals([ActionInterval("stand", 0, 20), ActionInterval("walk", 20, T)], VOCAB, T)
    assert action_segments(acts, VOCAB) == [(0, 20, "stand"), (20, T, "walk")]
    # two walks back to back (progress restarts), an overlap (both named), a gap (no action)
    acts = labels_from_intervals([ActionInterval("walk", 0, 10), ActionInterval("walk", 10, 20),
                                  ActionInterval("sit", 15, 25)], VOCAB, 30)
    assert action_segments(acts, VOCAB) == [(0, 10, "walk"), (10, 15, "walk"), (15, 20, "walk+sit"),
                                            (20, 25, "sit"), (25, 30, "")]
    assert action_segments(None, []) == []
    with pytest.raises(ValueError, match="action_names"):
        action_segments(np.zeros((5, 2)), VOCAB)


def test_import_map_is_complete_and_versioned():
    """Every vendored module is in the map, no relative import is left (a data: URL cannot resolve one), and
    the README names the version the vendored build reports."""
    imports = three_import_map()["imports"]
    assert set(imports) == set(THREE_MODULES)
    for spec, url in imports.items():
        assert url.startswith("data:text/javascript;base64,")
        code = base64.b64decode(url.split(",", 1)[1]).decode()
        for m in re.finditer(r"""\b(?:from|import)\s*["']([^"']+)["']""", code):
            assert not m.group(1).startswith("."), f"{spec} still imports {m.group(1)}"
    core = (VENDOR / "build" / "three.core.min.js").read_text()
    name = re.search(r"([\w$]+) as REVISION\b", core).group(1)  # minified: const t="185" ... export{t as REVISION}
    revision = re.search(rf"""(?<![\w$]){re.escape(name)}\s*=\s*["'](\d+)["']""", core).group(1)
    assert f"0.{revision}.0" in (VENDOR / "README.md").read_text()
    assert "MIT" in (VENDOR / "LICENSE").read_text()


def test_page_is_self_contained(tmp_path):
    seq = walking()
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, :3, 3] = seq.joints[:, JOINT_NAMES.index("right_wrist")]
    seq.objects["box_0"] = ObjectTrack(pose=pose, category="box")  # tracked; the scene has no mesh for it
    out = write_html([seq], tmp_path / "v.html", [SceneView(static=[room_mesh()], dynamic={})], ["walk"])
    page = out.read_text()
    # nothing is fetched: no src/href attribute, no http(s) URL outside comments and licence text
    assert not re.search(r"""<(script|link|img)[^>]*\s(src|href)=""", page)
    data = json.loads(re.search(r'<script type="application/json" id="trumans-data">(.*?)</script>', page, re.S).group(1))
    (s,) = data["sequences"]
    glb = base64.b64decode(s["glb"])
    assert glb[:4] == b"glTF"
    gltf = json.loads(glb[20:20 + int.from_bytes(glb[12:16], "little")])
    names = {n.get("name") for n in gltf["nodes"]}
    assert {"static_0", "box_0", "pelvis"} <= names  # the scene, the marker cube of the tracked box, the body
    assert any(c["target"]["node"] == [n.get("name") for n in gltf["nodes"]].index("box_0")
               for c in gltf["animations"][0]["channels"])
    assert s["frames"] == T and s["segments"] == [[0, 20, "stand"], [20, T, "walk"]]
    assert s["goals"] == [[T - 1, 0.75, 0.0, 0.9, "pelvis"]]
    assert np.frombuffer(base64.b64decode(s["contacts"]), np.uint8).reshape(T, 24)[0, JOINT_NAMES.index("left_foot")] == 1
    assert data["duration"] == pytest.approx((T - 1) / FPS)


def test_side_by_side_offsets_do_not_overlap(tmp_path):
    out = write_html([walking(), walking(0.5)], tmp_path / "v.html", None, ["a", "b"])
    data = json.loads(re.search(r'id="trumans-data">(.*?)</script>', out.read_text(), re.S).group(1))
    a, b = data["sequences"]
    assert b["bounds"][0][0] >= a["bounds"][1][0] + 0.99  # GAP_M apart along +x
    assert a["offset"] == [0.0, 0.0, 0.0]


def test_bad_input(tmp_path):
    with pytest.raises(ValueError, match=r"\.html"):
        write_html([walking()], tmp_path / "v.png")
    with pytest.raises(ValueError, match="one scene"):
        write_html([walking(), walking()], tmp_path / "v.html", [None])
    bad = walking()
    bad.extra["goals"] = np.zeros((2, 3))
    with pytest.raises(ValueError, match="goals"):
        write_html([bad], tmp_path / "v.html")
    bad = walking()
    bad.objects["box_0"] = ObjectTrack(pose=np.full((T, 4, 4), np.nan), category="box")
    with pytest.raises(ValueError, match="box_0"):
        write_html([bad], tmp_path / "v.html")
    with pytest.raises(ValueError, match=r"\.html"):
        cli_main(["view", str(tmp_path / "x.npz"), "--html", str(tmp_path / "v.txt")])
    assert not list(tmp_path.iterdir())


# ---- the page in a browser ----------------------------------------------------------------------------------


def chromium(url: str, *args: str) -> subprocess.Popen:
    """Headless Chromium with software WebGL (SwiftShader) on ``url``; stdout piped."""
    cmd = [CHROMIUM, "--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
           "--disable-gpu-sandbox", "--no-first-run", "--disable-extensions", "--hide-scrollbars",
           "--window-size=640,480", "--virtual-time-budget=1500", *args, url]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)


def body_pixels(png: Path, height: int) -> np.ndarray:
    """(n, 2) (x, y) of the body's blue pixels in the 3D view (the top ``height`` rows of the page)."""
    img = imageio.imread(png)[:height, :, :3].astype(int)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    ys, xs = np.nonzero((b > 120) & (b - r > 45) & (b - g > 15))
    return np.stack([xs, ys], 1)


def test_viewer_plays_in_headless_chromium(tmp_path, capsys):
    if CHROMIUM is None:
        why = "chromium is not installed (apt-get install -y chromium; `make test` installs it when run as root)"
        if os.environ.get("TRUMANS_REQUIRE_CHROMIUM"):  # .ci/run: the browser test must run in CI
            pytest.fail(why)
        pytest.skip(why)
    mesh = tmp_path / "room.ply"
    room_mesh().export(mesh)
    paths = []
    for k, y in enumerate((0.0, -0.5)):  # two sequences side by side, each in its own (mesh) scene
        seq = walking(y)
        seq.scene = str(mesh)
        paths.append(tmp_path / f"s{k}.npz")
        save_sequence(seq, paths[-1])
    out = tmp_path / "view.html"
    assert cli_main(["view", *map(str, paths), "--html", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1]) == {"html": str(out)}
    url = out.resolve().as_uri()
    t0, t1, size = 0.3, 1.9, "640x300"  # a fixed canvas size: the same view in the DOM and the screenshot runs
    runs = [chromium(f"{url}#t={t1}&paused&size={size}", "--dump-dom"),
            chromium(f"{url}#t={t0}&paused&size={size}", f"--screenshot={tmp_path / 'a.png'}"),
            chromium(f"{url}#t={t1}&paused&size={size}", f"--screenshot={tmp_path / 'b.png'}")]
    try:
        dom = runs[0].communicate(timeout=180)[0]
        for r in runs[1:]:
            r.wait(timeout=180)
    finally:
        for r in runs:
            if r.poll() is None:
                r.kill()
    status = json.loads(htmllib.unescape(re.search(r'<pre id="status">(.*?)</pre>', dom, re.S).group(1)))
    assert status["errors"] == [] and status["warnings"] == [], status
    assert status["ready"] and status["sequences"] == 2 and not status["playing"]
    assert status["t"] == pytest.approx(t1) and status["frames"] == [round(t1 * FPS)] * 2
    assert status["actions"] == ["walk", "walk"]
    assert status["contacts"] == [["right_wrist"], ["right_wrist"]]
    assert status["goals"] == [1, 1]
    w, h = status["canvas_px"]
    assert f"{w}x{h}" == size
    a, b = body_pixels(tmp_path / "a.png", h), body_pixels(tmp_path / "b.png", h)
    assert len(a) > 300 and len(b) > 300, (len(a), len(b))  # both bodies drawn
    # between t0 (still standing) and t1 (frame 57) the bodies walked 1.39 m along +x: their pixels moved right
    assert b[:, 0].mean() - a[:, 0].mean() > 15
    # the joints in contact are drawn as red spheres (no other red in this page: actions are orange and green)
    for png in ("a.png", "b.png"):
        img = imageio.imread(tmp_path / png)[:h, :, :3].astype(int)
        red = (img[..., 0] > 190) & (img[..., 1] < 70) & (img[..., 2] < 70)
        assert red.sum() > 10, png
    # the page's projected pelvis (at t1) lies on a drawn body: body pixels around it
    for px, py in status["pelvis_px"]:
        near = b[(np.abs(b[:, 0] - px) < 40) & (np.abs(b[:, 1] - py) < 60)]
        assert len(near) > 30, (px, py)
