"""Rebuild data/mocap/cmu_corpus.npz and its clip list data/mocap/cmu_clips.csv from the raw CMU
files (deterministic: the same inputs give the same bytes).

Inputs (see data/mocap/LICENSE.md for what they are):

- ``--raw``: the folder ``../shared/data/mocap/cmu_subset.tar.xz`` was extracted into (holds raw/),
  with ``--clips``, that archive's ``clips.csv`` (181 clips, incl. the 10 BVH files used as they are);
- ``--mirrors``: a folder holding git snapshots of the three GitHub repositories that vendor the CMU
  "Huge FBX Mocap Library", one per repository, named ``<owner>+<name>`` (a bare git dir, or a
  folder with the git dir in ``repo/``): bbudian+FirstPersonLeague, loki1213+Top-Down-shooter,
  EmileEmile+MasterThesisCups. ``git clone --bare https://github.com/<owner>/<name>
  <mirror-dir>/<owner>+<name>`` makes one; the commits used are in ``--library``;
- ``--library``: ``fbx_hugelib_availability.csv`` (every library clip: repo, commit, path, git blob),
  ``--index``: ``cmu-mocap-index-text.txt`` (CMU's description of every trial);
- ``--rules``: the selection rules (default scripts/cmu_select_rules.csv).

The command (12 min on one core; ``--workers 2`` halves it, ``--cache DIR`` keeps converted clips so
that a change of the rules takes 25 s; neither changes a byte of the output)::

    mkdir -p /tmp/mocap && tar xJf ../shared/data/mocap/cmu_subset.tar.xz -C /tmp/mocap
    OMP_NUM_THREADS=1 python scripts/build_mocap_corpus.py --raw /tmp/mocap \\
        --clips ../shared/data/mocap/clips.csv --mirrors <mirror-dir> \\
        --library ../shared/data/mocap/index/fbx_hugelib_availability.csv \\
        --index ../shared/data/mocap/index/cmu-mocap-index-text.txt --workers 2 --cache /tmp/cmu_cache

Selection, per clip of the library (and of the archive):

1. **By description** (``--rules``; first matching rule wins): everyday indoor motion and general
   locomotion are kept; duplicates (77 = 139, 105 = 91, 73 = 70), two-person clips, playground and
   apparatus, sports, martial arts, dance, acrobatics, animal / character imitations, jumps,
   running and clips without a description are not (they are not converted).
2. **Conversion** with ``trumans.mocap_corpus.convert_clip`` (FBX 6.1 Daz-style or BVH, the
   converter's T-pose frame dropped, resampled once to 30 fps by a zero-phase 6 Hz low-pass and a
   cubic spline, feet on the floor, per-frame states). A clip that fails is excluded with its error.
   The file comes from the archive when ``--clips`` lists the clip (same bytes as the snapshots for
   FBX; the 10 BVH clips exist only there), else from the snapshot by its git blob; both are checked
   against the blob id.
3. **Motion checks** (``motion_checks``; the thresholds are the constants below): a zero-length bone, a flipped frame
   (the hip axis, seen from above, turns > 90 deg between two frames) or a joint jump (> 15 m/s
   between two frames), feet far under the floor (1st percentile of the lowest foot < -8 cm),
   running (95th percentile of the pelvis ground speed > 3 m/s), standing straight with both feet
   > 10 cm off the floor on > 10 % of frames (stairs, steps, ledges, jumps: the project's rooms
   have flat floors), shorter than 1 s.
4. **Content duplicates**: a clip whose converted joints equal an earlier clip's is dropped.

Clips of ``HELD_OUT_SUBJECTS`` form the test split. Every library clip gets a row in ``--list``
(its source, blob, decision and reason, and the motion-check figures of converted clips), so the
selection is auditable.
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import re
import subprocess
import sys
import tempfile
import time
import warnings
import multiprocessing
from contextlib import nullcontext
from collections import Counter, defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from trumans.mocap_corpus import CORPUS_PATH, HELD_OUT_SUBJECTS, MocapClip, convert_clip, write_corpus  # noqa: E402
from trumans.motion_labels import MOTION_STATES, body_features  # noqa: E402
from trumans.skeleton import FOOT_JOINTS, FOOT_REST_HEIGHT, JOINT_INDEX, PARENTS  # noqa: E402

RULES_PATH = ROOT / "scripts" / "cmu_select_rules.csv"
LIST_PATH = ROOT / "data" / "mocap" / "cmu_clips.csv"
FPS = 30.0
# motion checks on the converted 30-fps joints (m, s)
MIN_BONE_M = 0.01            # a median bone length below this: the skeleton is broken
MAX_HIP_TURN_DEG = 90.0      # the hip axis turns more than this between two frames: a flipped frame
MAX_JOINT_STEP_M = 15.0 / FPS  # a joint moves faster than 15 m/s between two frames: a jump in the data
MIN_FLOOR_P1_M = -0.08       # 1st percentile of the lowest foot joint below this: feet under the floor
MAX_SPEED_P95 = 3.0          # 95th percentile of the pelvis ground speed (0.5 s mean) above this: running
RAISED_M = 0.10              # lowest foot joint this far above its standing height while the body stands straight ...
MAX_RAISED_SHARE = 0.10      # ... with the body upright on more than this share of frames: off the floor
MIN_SECONDS = 1.0
LIST_FIELDS = ["clip", "subject", "description", "split", "reason", "source", "commit", "path", "git_blob",
               "file_seconds", "corpus_seconds", "speed_p95_mps", "raised_share", "floor_p1_m", "min_bone_m",
               "max_hip_turn_deg", "max_joint_step_m"]
UNKNOWN = {"", "?", "unknown", "clean", "cleaned"}


@dataclass
class Rule:
    clips: re.Pattern | None
    pattern: re.Pattern | None
    include: bool
    reason: str


def read_rules(path: Path) -> list[Rule]:
    """The selection rules: rows ``clips,pattern,decision,reason``; '#' rows are comments."""
    rules = []
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows or rows[0][:4] != ["clips", "pattern", "decision", "reason"]:
        raise ValueError(f"{path}: the first row must be 'clips,pattern,decision,reason'")
    for n, r in enumerate(rows[1:], 2):
        if not r or r[0].startswith("#"):
            continue
        if len(r) != 4 or r[2] not in ("include", "exclude"):
            raise ValueError(f"{path} row {n}: expected 4 fields with decision include|exclude, got {r}")
        try:
            rules.append(Rule(re.compile(r[0]) if r[0] else None, re.compile(r[1], re.I) if r[1] else None,
                              r[2] == "include", r[3]))
        except re.error as e:
            raise ValueError(f"{path} row {n}: bad regular expression ({e}); fix the rule") from None
    if not rules or rules[-1].clips or rules[-1].pattern:
        raise ValueError(f"{path}: the last rule must match everything (empty clips and pattern)")
    return rules


def decide(rules: list[Rule], clip: str, description: str) -> tuple[bool, str]:
    """(include?, reason) of the first rule matching the clip name and its description."""
    for r in rules:
        if (r.clips is None or r.clips.fullmatch(clip)) and (r.pattern is None or r.pattern.search(description)):
            return r.include, r.reason
    raise AssertionError("unreachable: the last rule matches everything")


def read_index(path: Path) -> tuple[dict[str, str], dict[str, str]]:
    """CMU's descriptions per trial and titles per subject from cmu-mocap-index-text.txt."""
    desc, titles = {}, {}
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        m = re.match(r"Subject #(\d+) \((.*)\)\s*$", line)
        if m:
            titles[f"{int(m.group(1)):02d}"] = m.group(2).strip()
            continue
        m = re.match(r"^(\d+_\d+)\t(.*?)\s*$", line)
        if m:
            desc[m.group(1)] = m.group(2)
    if len(desc) < 2000:
        raise ValueError(f"{path}: found {len(desc)} trial descriptions, expected ~2,500; pass cmu-mocap-index-text.txt")
    return desc, titles


def git_dir(mirrors: Path, repo: str) -> Path:
    """The git dir of a snapshot of ``owner/name`` under ``mirrors``."""
    owner, name = repo.split("/")
    for cand in (mirrors / f"{owner}+{name}" / "repo", mirrors / f"{owner}+{name}", mirrors / f"{owner}+{name}.git"):
        if (cand / "objects").is_dir():
            return cand
    raise FileNotFoundError(f"no git snapshot of {repo} under {mirrors}: expected {mirrors}/{owner}+{name} "
                            f"(git clone --bare https://github.com/{repo} {mirrors}/{owner}+{name})")


def blob_id(data: bytes) -> str:
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def read_blob(gd: Path, blob: str) -> bytes:
    data = subprocess.run(["git", "--git-dir", str(gd), "cat-file", "blob", blob], capture_output=True,
                          check=True).stdout
    if blob_id(data) != blob:
        raise ValueError(f"{gd}: blob {blob} reads back with id {blob_id(data)}")
    return data


def motion_checks(c: MocapClip) -> tuple[dict[str, float], str | None]:
    """The motion-check figures of a converted clip and the first failed check (or None)."""
    j = c.joints.astype(np.float64)
    bones = np.median(np.linalg.norm(j[:, 1:] - j[:, PARENTS[1:]], axis=-1), axis=0)
    across = j[:, JOINT_INDEX["left_hip"], :2] - j[:, JOINT_INDEX["right_hip"], :2]
    length = np.linalg.norm(across, axis=-1)
    ok = length > 0.5 * np.median(length)  # the hip axis is seen from above (not a body lying on its side)
    ang = np.arctan2(across[:, 1], across[:, 0])
    d = np.abs((np.diff(ang) + np.pi) % (2 * np.pi) - np.pi)[ok[1:] & ok[:-1]]
    turn = float(np.degrees(d.max(initial=0.0)))
    step = float(np.linalg.norm(np.diff(j, axis=0), axis=-1).max(initial=0.0))
    low = (j[:, list(FOOT_JOINTS), 2] - FOOT_REST_HEIGHT).min(axis=1)  # lowest foot joint above its standing height
    f = body_features(c.joints, c.fps)
    straight = (f["h"] > 0.9 * f["h_stand"]) & (f["thigh"] < np.deg2rad(25)) & (f["tilt"] < np.deg2rad(30))
    raised = float(np.mean(straight & (low > RAISED_M)))  # standing straight, not on the floor: a jump or a step
    fig = {"speed_p95_mps": float(np.percentile(f["speed"], 95)), "raised_share": raised,
           "floor_p1_m": float(np.percentile(low, 1)), "min_bone_m": float(bones.min()),
           "max_hip_turn_deg": turn, "max_joint_step_m": step}
    if len(j) < MIN_SECONDS * c.fps:
        return fig, f"shorter than {MIN_SECONDS:g} s"
    if fig["min_bone_m"] < MIN_BONE_M:
        return fig, "broken skeleton: zero-length bone"
    if turn > MAX_HIP_TURN_DEG or step > MAX_JOINT_STEP_M:
        return fig, "broken skeleton: flipped frame or joint jump"
    if fig["floor_p1_m"] < MIN_FLOOR_P1_M:
        return fig, "feet far under the floor"
    if fig["speed_p95_mps"] > MAX_SPEED_P95:
        return fig, f"running (pelvis speed p95 > {MAX_SPEED_P95:g} m/s)"
    if raised > MAX_RAISED_SHARE:
        return fig, f"standing with both feet off the floor on > {MAX_RAISED_SHARE:.0%} of frames (stairs, steps, jumps)"
    return fig, None


CONVERTER_FILES = ("trumans/mocap_corpus.py", "trumans/resample.py", "trumans/bvh.py", "trumans/motion_labels.py",
                   "trumans/importers/fbx.py", "trumans/importers/fbx_curves.py", "trumans/importers/fbx_nodes.py",
                   "trumans/importers/joint_maps.py", "trumans/importers/labels.py", "trumans/importers/bvh.py")


def converter_hash() -> str:
    """sha1 of the converter's source files: the key that keeps a --cache valid."""
    h = hashlib.sha1()
    for f in CONVERTER_FILES:
        if (ROOT / f).is_file():
            h.update((ROOT / f).read_bytes())
    return h.hexdigest()[:12]


def convert_job(job: tuple) -> tuple[str, MocapClip | None, str | None]:
    """Convert one clip: ``(clip, git_blob, (file or git dir, suffix or None), description, cache dir or None)``
    -> (clip, the converted clip or None, the reason it failed or None). The file's blob id is checked."""
    clip, blob, (src, suffix), description, cache = job
    cached = Path(cache) / f"{clip}_{blob[:12]}_{converter_hash()}.npz" if cache else None
    if cached is not None and cached.is_file():
        with np.load(cached, allow_pickle=False) as z:
            return clip, MocapClip(clip, str(z["subject"]), description, str(z["split"]), float(z["fps"]),
                                   z["joints"], z["states"]), None
    with tempfile.TemporaryDirectory() as tmp:
        if suffix is None:
            path = Path(src)
            if blob_id(path.read_bytes()) != blob:
                raise SystemExit(f"{path}: its git blob id is not {blob} (clips.csv); re-extract the archive")
        else:
            path = Path(tmp) / f"{clip}{suffix}"
            path.write_bytes(read_blob(Path(src), blob))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                c = convert_clip(path, clip, description, FPS)
        except Exception as e:  # noqa: BLE001 - any failure excludes the clip, with its error
            msg = str(e).replace(str(path), path.name)  # no temporary folder in the list: the same bytes every run
            return clip, None, f"conversion failed: {type(e).__name__}: {msg[:80]}"
    if cached is not None:
        cached.parent.mkdir(parents=True, exist_ok=True)
        part = cached.with_suffix(".part.npz")
        np.savez(part, subject=c.subject, split=c.split, fps=c.fps, joints=c.joints, states=c.states)
        part.replace(cached)
    return clip, c, None


def _key(clip: str) -> tuple[int, int]:
    s, t = clip.split("_")
    return int(s), int(t)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--raw", required=True, help="folder cmu_subset.tar.xz was extracted into (holds raw/)")
    p.add_argument("--clips", required=True, help="the archive's clips.csv")
    p.add_argument("--mirrors", required=True, help="folder of the three FBX-library snapshots (<owner>+<name>)")
    p.add_argument("--library", required=True, help="fbx_hugelib_availability.csv (repo, commit, path, git blob per clip)")
    p.add_argument("--index", required=True, help="cmu-mocap-index-text.txt (CMU's descriptions)")
    p.add_argument("--rules", default=str(RULES_PATH), help="selection rules csv (default scripts/cmu_select_rules.csv)")
    p.add_argument("--out", default=str(CORPUS_PATH), help="npz to write (default data/mocap/cmu_corpus.npz)")
    p.add_argument("--list", default=str(LIST_PATH), help="clip list csv to write (default data/mocap/cmu_clips.csv)")
    p.add_argument("--limit", type=int, help="convert only the first N selected clips (a quick check)")
    p.add_argument("--workers", type=int, default=1, help="conversion processes (the output does not depend on it)")
    p.add_argument("--cache", help="folder keeping converted clips between runs (keyed by file blob and converter "
                                   "source), so that changing the rules does not convert again")
    args = p.parse_args(argv)

    # every input checked before the conversions
    for name in ("raw", "mirrors"):
        if not Path(getattr(args, name)).is_dir():
            raise SystemExit(f"--{name} {getattr(args, name)} is not a folder; see the command in this script's docstring")
    for name in ("clips", "library", "index", "rules"):
        if not Path(getattr(args, name)).is_file():
            raise SystemExit(f"--{name} {getattr(args, name)} does not exist; see the command in this script's docstring")
    rules = read_rules(Path(args.rules))
    desc, titles = read_index(Path(args.index))
    archive = {r["clip"]: r for r in csv.DictReader(open(args.clips, newline=""))}
    library = {r["clip"]: r for r in csv.DictReader(open(args.library, newline=""))}
    if not archive or "local_path" not in next(iter(archive.values())):
        raise SystemExit(f"--clips {args.clips}: expected the archive's clips.csv (with local_path)")
    if not library or "git_blob" not in next(iter(library.values())):
        raise SystemExit(f"--library {args.library}: expected fbx_hugelib_availability.csv (with git_blob)")
    names = sorted(set(archive) | set(library), key=_key)

    rows: dict[str, dict] = {}
    todo = []
    for clip in names:
        lib, arc = library.get(clip), archive.get(clip)
        d = desc.get(clip) or (arc["cmu_description"] if arc else "")
        text = titles.get(clip.split("_")[0], "") if d.strip().lower() in UNKNOWN else d
        row = {"clip": clip, "subject": clip.split("_")[0], "description": d}
        if arc:
            row.update(source="archive:" + arc["local_path"], commit=arc["commit"], path=arc["path_in_repo"],
                       git_blob=arc["git_blob"], file_seconds=arc["duration_s"])
        else:
            row.update(source=lib["repo"], commit=lib["commit"], path=lib["path"], git_blob=lib["git_blob"],
                       file_seconds=lib["duration_s_at_file_timing"])
        keep, reason = decide(rules, clip, text)
        if keep and not arc and lib["missing_in_snapshot"] == "True":
            keep, reason = False, "file missing from the snapshot"
        row.update(split="" if keep else "excluded", reason=reason)
        rows[clip] = row
        if keep:
            todo.append(clip)
    if args.limit:
        for clip in todo[args.limit:]:
            rows[clip].update(split="excluded", reason="not converted (--limit)")
        todo = todo[:args.limit]
    gdirs = {repo: git_dir(Path(args.mirrors), repo) for repo in sorted({rows[c]["source"] for c in todo
                                                                         if not rows[c]["source"].startswith("archive:")})}
    for clip in todo:
        if rows[clip]["source"].startswith("archive:"):
            path = Path(args.raw) / archive[clip]["local_path"]
            if not path.is_file():
                raise SystemExit(f"{path} (clip {clip}) does not exist; extract cmu_subset.tar.xz into --raw")
    print(f"{len(names)} clips listed, {len(todo)} selected by description; converting", file=sys.stderr)

    jobs = []
    for clip in todo:
        row = rows[clip]
        if row["source"].startswith("archive:"):
            src = (str(Path(args.raw) / archive[clip]["local_path"]), None)
        else:
            src = (str(gdirs[row["source"]]), Path(row["path"]).suffix)
        jobs.append((clip, row["git_blob"], src, row["description"], args.cache))
    clips: list[MocapClip] = []
    seen: dict[bytes, str] = {}
    t0 = time.time()
    with multiprocessing.get_context("spawn").Pool(args.workers) if args.workers > 1 else nullcontext() as pool:
        results = pool.imap(convert_job, jobs, chunksize=4) if pool else map(convert_job, jobs)
        for i, (clip, c, err) in enumerate(results):  # in the order of todo whatever the workers: same bytes
            row = rows[clip]
            if c is None:
                row.update(split="excluded", reason=err)
                continue
            fig, fail = motion_checks(c)
            row.update({k: f"{v:.4g}" for k, v in fig.items()}, corpus_seconds=f"{len(c.joints) / FPS:.2f}")
            digest = hashlib.sha1(np.ascontiguousarray(c.joints).tobytes()).digest()
            if fail is None and digest in seen:
                fail = f"duplicate of {seen[digest]} (same joints)"
            if fail:
                row.update(split="excluded", reason=fail)
                continue
            seen[digest] = clip
            row["split"] = c.split
            clips.append(c)
            if i % 50 == 0:
                print(f"{i:5d}/{len(todo)} {clip:>7} {time.time() - t0:7.1f} s", file=sys.stderr)

    meta = {"source": "CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu), see data/mocap/LICENSE.md",
            "held_out_subjects": list(HELD_OUT_SUBJECTS), "fps": FPS, "quantum_m": 1e-4,
            "clip_list": "data/mocap/cmu_clips.csv", "rules": "scripts/cmu_select_rules.csv",
            "rules_sha1": hashlib.sha1(Path(args.rules).read_bytes()).hexdigest()}
    write_corpus(args.out, clips, meta)
    Path(args.list).parent.mkdir(parents=True, exist_ok=True)
    with open(args.list, "w", newline="") as f:
        w = csv.DictWriter(f, LIST_FIELDS, lineterminator="\n")
        w.writeheader()
        for clip in names:
            w.writerow({k: rows[clip].get(k, "") for k in LIST_FIELDS})
    print(summary(clips, rows, time.time() - t0), file=sys.stderr)
    print(f"wrote {args.out} and {args.list}", file=sys.stderr)
    return 0


def summary(clips: list[MocapClip], rows: dict[str, dict], seconds: float) -> str:
    """Minutes per split and per motion state, and the excluded clips per reason."""
    out = [f"{len(clips)} clips, {sum(len(c.joints) for c in clips) / FPS / 60:.1f} min, converted in {seconds:.0f} s"]
    for split in ("train", "test"):
        cs = [c for c in clips if c.split == split]
        st = np.concatenate([c.states for c in cs]) if cs else np.zeros(0, int)
        per = ", ".join(f"{s} {np.sum(st == i) / FPS / 60:.1f}" for i, s in enumerate(MOTION_STATES))
        out.append(f"  {split}: {len(cs)} clips, {len(st) / FPS / 60:.1f} min ({per})")
    reasons: Counter = Counter()
    secs: dict[str, float] = defaultdict(float)
    for r in rows.values():
        if r["split"] == "excluded":
            key = re.sub(r"duplicate of \S+ \(same joints\)", "duplicate of an earlier clip (same joints)", r["reason"])
            reasons[key] += 1
            secs[key] += float(r["file_seconds"] or 0)
    out.append("  excluded:")
    out += [f"    {n:5d} clips {secs[k] / 60:6.1f} min  {k}" for k, n in reasons.most_common()]
    return "\n".join(out)


if __name__ == "__main__":
    sys.exit(main())
