"""Render sequences for a person to look at: animated skeleton + scene (GIF/MP4) and a top-down PNG.

Matplotlib figures on the Agg canvas (never pyplot, so importing this module leaves the global
backend alone and it runs headless). Scene meshes are drawn once; per frame only the bones, the
moving objects and the camera limits change.
"""
from __future__ import annotations

import os

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import trimesh
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

from trumans.sequence import Sequence, atomic_write
from trumans.skeleton import JOINT_NAMES, PARENTS

__all__ = ["SceneView", "render_animation", "render_still", "render_topdown"]

_BONES = np.array([(PARENTS[j], j) for j in range(1, len(PARENTS))])
_LEFT = np.array([n.startswith("left_") for n in JOINT_NAMES])
_COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"]


@dataclass
class SceneView:
    """What the renderer draws of a scene: static meshes (world), dynamic object meshes (object
    frame, posed per frame by the sequence's ``objects/<name>/pose``) and an optional occupancy
    grid (``grid (Nx,Ny,Nz) bool``, ``origin`` voxel-(0,0,0) centre, ``voxel`` m) for the top-down map."""

    static: list[trimesh.Trimesh]
    dynamic: dict[str, trimesh.Trimesh]
    grid: np.ndarray | None = None
    origin: np.ndarray | None = None
    voxel: float | None = None
    # the scene's own (4, 4) world-from-object pose of dynamic objects (where a sequence does not move them)
    dynamic_pose: dict[str, np.ndarray] = field(default_factory=dict)


def _figure(width_in: float, height_in: float) -> Figure:
    """A figure drawn by the Agg canvas (no pyplot, no global backend)."""
    fig = Figure(figsize=(width_in, height_in), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _decimate(m: trimesh.Trimesh, max_faces: int = 4000) -> np.ndarray:
    tri = m.triangles
    if len(tri) > max_faces:
        tri = tri[np.linspace(0, len(tri) - 1, max_faces).astype(int)]
    return tri


def _frame_bounds(joints: list[np.ndarray], margin: float = 0.5) -> np.ndarray:
    allj = np.concatenate([j.reshape(-1, 3) for j in joints])
    lo, hi = allj.min(0) - margin, allj.max(0) + margin
    lo[2], hi[2] = 0.0, max(hi[2], 2.0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    return np.stack([c - r, c + r])


Scenes = SceneView | list[SceneView | None] | None


def _per_sequence(scene: Scenes, n: int) -> list[SceneView | None]:
    if isinstance(scene, list):
        if len(scene) != n:
            raise ValueError(f"got {len(scene)} scenes for {n} sequences; pass one scene per sequence (or one for all)")
        return scene
    return [scene] * n


class _Panels:
    """A row of 3D panels, one per sequence, each with its own scene; ``draw(t)`` poses frame t."""

    def __init__(self, seqs: list[Sequence], scenes: list[SceneView | None], camera: str, size_px: int,
                 titles: list[str] | None) -> None:
        n = len(seqs)
        self.seqs, self.camera = seqs, camera
        self.fig = _figure(size_px / 100 * n, size_px / 100)
        self.axes, self.bones, self.objs = [], [], []
        self.fixed = _frame_bounds([s.joints for s in seqs])
        for k, (s, scene) in enumerate(zip(seqs, scenes)):
            ax = self.fig.add_subplot(1, n, k + 1, projection="3d")
            ax.set_box_aspect((1, 1, 1))
            ax.view_init(elev=25, azim=-60)
            ax.set_xlabel("x"), ax.set_ylabel("y"), ax.set_zlabel("z")
            if titles:
                ax.set_title(titles[k], fontsize=9)
            cols = {}
            if scene is not None:
                for m in scene.static:
                    ax.add_collection3d(Poly3DCollection(_decimate(m), facecolor="#bbbbbb", edgecolor="none", alpha=0.25))
                for name, m in scene.dynamic.items():
                    if name in s.objects:
                        pc = Poly3DCollection(_decimate(m, 800), facecolor="#e6a23c", edgecolor="none", alpha=0.6)
                        ax.add_collection3d(pc)
                        cols[name] = (pc, _decimate(m, 800))
            j0 = s.joints[0]
            lc = Line3DCollection(np.stack([j0[_BONES[:, 0]], j0[_BONES[:, 1]]], axis=1), linewidths=2.5)
            ax.add_collection3d(lc, autolim=False)
            self.axes.append(ax), self.bones.append(lc), self.objs.append(cols)

    def draw(self, t: int | list[int]) -> np.ndarray:
        """Pose every panel at frame t (or panel k at t[k]); returns the RGB image (H, W, 3) uint8."""
        ts = t if isinstance(t, list) else [t] * len(self.seqs)
        for k, (s, t) in enumerate(zip(self.seqs, ts)):
            j = s.joints[t]
            self.bones[k].set_segments(np.stack([j[_BONES[:, 0]], j[_BONES[:, 1]]], axis=1))
            contact = s.contacts[t] if s.contacts is not None else np.zeros(len(j), bool)
            colors = np.where(contact[_BONES[:, 1]], "#ff7f0e", np.where(_LEFT[_BONES[:, 1]], _COLORS[0], _COLORS[1]))
            self.bones[k].set_color(list(colors))
            for name, (pc, tri) in self.objs[k].items():
                P = s.objects[name].pose[t]
                pc.set_verts(tri @ P[:3, :3].T + P[:3, 3])
            b = self.fixed
            if self.camera == "follow":
                c = j[0]
                b = np.stack([c - 1.5, c + 1.5])
                b[:, 2] = [0.0, 3.0]
            ax = self.axes[k]
            ax.set_xlim(b[0, 0], b[1, 0]), ax.set_ylim(b[0, 1], b[1, 1]), ax.set_zlim(b[0, 2], b[1, 2])
        self.fig.canvas.draw()
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        self.fig.clear()


def _check_seqs(seqs: list[Sequence]) -> int:
    if not seqs:
        raise ValueError("rendering needs at least one sequence")
    return min(s.num_frames for s in seqs)


def render_animation(
    seqs: list[Sequence],
    out: str | Path,
    scene: Scenes = None,
    camera: Literal["fixed", "follow"] = "fixed",
    stride: int = 1,
    fps: float | None = None,
    size_px: int = 480,
    titles: list[str] | None = None,
) -> Path:
    """Render one or more sequences side by side to ``out`` (.gif or .mp4). Returns the path.

    seqs: sequences in the same world frame (e.g. original and augmented); scene: one SceneView for
    all panels or a list with one per sequence (an augmented sequence lives in its changed scene);
    stride: keep every ``stride``-th frame; fps: output rate (default: the sequence rate / stride).
    """
    import imageio.v2 as imageio

    out = Path(out)
    if out.suffix not in (".gif", ".mp4"):
        raise ValueError(f"animation output must end in .gif or .mp4, got {out.name}")
    T = _check_seqs(seqs)
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    panels = _Panels(seqs, _per_sequence(scene, len(seqs)), camera, size_px, titles)
    images = [panels.draw(t) for t in range(0, T, stride)]
    panels.close()
    rate = fps or seqs[0].fps / stride

    def _write(tmp: str) -> None:
        if out.suffix == ".gif":
            imageio.mimsave(tmp, images, format="GIF", duration=1000.0 / rate, loop=0)
        else:  # ffmpeg picks the container from the file name: write "<tmp>.mp4", then move it onto tmp
            named = tmp + ".mp4"
            try:
                imageio.mimsave(named, images, format="FFMPEG", fps=rate, codec="libx264", macro_block_size=1)
                os.replace(named, tmp)
            finally:
                if os.path.exists(named):
                    os.unlink(named)

    atomic_write(out, _write)
    return out


def render_still(seqs: list[Sequence], out: str | Path, frame: int | list[int], scene: Scenes = None,
                 size_px: int = 480, titles: list[str] | None = None) -> Path:
    """Frame ``frame`` (or one frame per sequence) of one or more sequences side by side, as a
    PNG (same panels as ``render_animation``). Returns the path."""
    import imageio.v2 as imageio

    out = Path(out)
    if out.suffix != ".png":
        raise ValueError(f"still output must end in .png, got {out.name}")
    _check_seqs(seqs)
    frames = frame if isinstance(frame, list) else [frame] * len(seqs)
    if len(frames) != len(seqs):
        raise ValueError(f"got {len(frames)} frames for {len(seqs)} sequences")
    for s, f in zip(seqs, frames):
        if not 0 <= f < s.num_frames:
            raise ValueError(f"frame must be in [0, {s.num_frames}), got {f}")
    panels = _Panels(seqs, _per_sequence(scene, len(seqs)), "fixed", size_px, titles)
    image = panels.draw(frames)
    panels.close()
    atomic_write(out, lambda tmp: imageio.imwrite(tmp, image, format="PNG"))
    return out


def render_topdown(seq: Sequence, out: str | Path, scene: SceneView | None = None,
                   goals: np.ndarray | None = None, z_range: tuple[float, float] = (0.1, 1.8)) -> Path:
    """Top-down PNG: occupancy between ``z_range`` (grey), the pelvis path coloured by time,
    start / end markers, optional goals (K, 2 or 3), and joints in contact (orange)."""
    out = Path(out)
    fig = _figure(6, 6)
    ax = fig.add_subplot()
    if scene is not None and scene.grid is not None:
        v, o = float(scene.voxel), np.asarray(scene.origin)
        k0 = max(int(np.floor((z_range[0] - o[2]) / v)), 0)
        k1 = max(int(np.ceil((z_range[1] - o[2]) / v)), k0 + 1)
        occ2d = scene.grid[:, :, k0:k1].any(axis=2)
        ext = [o[0] - v / 2, o[0] + v * (occ2d.shape[0] - 0.5), o[1] - v / 2, o[1] + v * (occ2d.shape[1] - 0.5)]
        ax.imshow(occ2d.T, origin="lower", extent=ext, cmap="Greys", alpha=0.6, interpolation="nearest")
    elif scene is not None:
        for m in scene.static:
            tri = _decimate(m)
            ax.fill(tri[:, [0, 1, 2, 0], 0].T, tri[:, [0, 1, 2, 0], 1].T, color="#999999", alpha=0.05, lw=0)
    p = seq.joints[:, 0, :2]
    sc = ax.scatter(p[:, 0], p[:, 1], c=np.arange(len(p)) / seq.fps, s=4, cmap="viridis")
    fig.colorbar(sc, ax=ax, label="time (s)", shrink=0.8)
    ax.plot(*p[0], "go", ms=9, label="start")
    ax.plot(*p[-1], "rs", ms=9, label="end")
    if goals is not None and len(goals):
        g = np.asarray(goals)
        ax.plot(g[:, 0], g[:, 1], "k*", ms=12, label="goals")
    if seq.contacts is not None and seq.contacts.any():
        c = seq.joints[seq.contacts]
        ax.scatter(c[:, 0], c[:, 1], s=2, color="#ff7f0e", alpha=0.3, label="contacts")
    for name, ob in seq.objects.items():
        ax.plot(ob.pose[:, 0, 3], ob.pose[:, 1, 3], "-", lw=1, color="#e6a23c")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)"), ax.set_ylabel("y (m)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"{seq.scene or 'sequence'}: {seq.num_frames} frames @ {seq.fps:g} fps", fontsize=9)

    def _write(tmp: str) -> None:
        fig.savefig(tmp, format="png", bbox_inches="tight")

    atomic_write(out, _write)
    return out
