#!/usr/bin/env python3
"""Cloth accuracy metrics, one code path for every solver's output (numpy).

A run directory holds frame_NNNN.obj (the `v` lines in the solver's vertex order; frame 0 the
initial state, frame k the state after k frames; `f` lines optional) and stats.csv with a
`frame` and a `wall_s` column (our host writes both; bench/blender/blender_run.py writes the
same for Blender). From it:

* `load_frames(dir)` -> (F+1, n, 3) positions; `read_faces(obj)` -> (t, 3) triangles;
  `wall_times(dir)` -> wall_s of frames 1..F;
* `extension_strain(frames, edges)` -> per-frame max and RMS of the extension strain
  max(0, l/l0 - 1) over the given edges (rest lengths l0 from frame 0; a compressed edge counts
  as 0), frames 1..F; `strain_summary` turns them into the mean of each, the peak and its frame,
  and the share of frames whose max is at most 1 %;
* `penetration(frames, colliders)` -> the deepest any vertex gets below an analytic collider's
  surface (sphere: R - |x - c|, plane: -(x - p).n), over all frames, its frame, and the
  deepest in the last frame;
* `intersecting_pairs(x, triangles)` -> the triangle pairs that share no vertex and intersect
  (a grid broad phase, then an exact-sign segment-triangle test in float64, coplanar pairs in
  2D). `python3 bench/cloth_metrics.py --self-test` checks it on pairs whose answer is known.

Importable by any benchmark script: `sys.path.insert(0, "bench"); import cloth_metrics`.
"""

import glob
import os
import sys

import numpy as np

THRESHOLD = 0.01   # "max strain within 1 %"


# ---------------------------------------------------------------- reading a run

def read_obj_vertices(path):
    """The `v x y z` lines of an OBJ file as an (n, 3) float64 array."""
    with open(path) as f:
        rows = [line[2:] for line in f if line.startswith("v ")]
    return np.array(" ".join(rows).split(), dtype=np.float64).reshape(-1, 3)


def read_faces(path):
    """The `f` lines of an OBJ file as a (t, 3) array of 0-based vertex indices (triangles;
    `a/b/c` forms keep the vertex index)."""
    faces = []
    with open(path) as f:
        for line in f:
            if line.startswith("f "):
                faces.append([int(tok.split("/")[0]) - 1 for tok in line.split()[1:4]])
    return np.array(faces, dtype=np.int64).reshape(-1, 3)


def frame_files(out_dir):
    return sorted(glob.glob(os.path.join(out_dir, "frame_*.obj")))


def load_frames(out_dir):
    """Every frame of a run, (F+1, n, 3)."""
    return np.stack([read_obj_vertices(p) for p in frame_files(out_dir)])


def wall_times(out_dir, column="wall_s"):
    """A column of stats.csv (default wall_s) for frames 1..F, in frame order."""
    with open(os.path.join(out_dir, "stats.csv")) as f:
        header = f.readline().strip().split(",")
        rows = [line.strip().split(",") for line in f if line.strip()]
    fi, ci = header.index("frame"), header.index(column)
    return np.array([float(r[ci]) for r in sorted(rows, key=lambda r: int(r[fi]))])


# ---------------------------------------------------------------- strain

def mesh_edges(triangles):
    """The unique edges (e, 2) of a triangle mesh, each as (low, high)."""
    t = np.asarray(triangles)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def extension_strain(frames, edges):
    """Per-frame (max, RMS) of max(0, l/l0 - 1) over `edges`, for frames 1..F (l0 from 0)."""
    a, b = edges[:, 0], edges[:, 1]
    l0 = np.linalg.norm(frames[0, a] - frames[0, b], axis=1)
    ext = np.maximum(np.linalg.norm(frames[1:, a] - frames[1:, b], axis=2) / l0 - 1.0, 0.0)
    return ext.max(axis=1), np.sqrt((ext * ext).mean(axis=1))


def strain_summary(smax, srms, threshold=THRESHOLD):
    """The figures of a run's strain: the mean over frames 1..F of the per-frame max and RMS,
    the peak max and its frame (1-based), the share of frames with max <= threshold, and the
    last frame's max and RMS."""
    k = int(np.argmax(smax))
    return {"strain_max": float(smax.mean()), "strain_rms": float(srms.mean()),
            "strain_peak": float(smax[k]), "strain_peak_frame": k + 1,
            "share_max_within_1pct": float((smax <= threshold).mean()),
            "strain_max_end": float(smax[-1]), "strain_rms_end": float(srms[-1])}


# ---------------------------------------------------------------- colliders

def collider_depth(x, collider):
    """Depth (m, >= 0) of each point of x (..., 3) below the collider's surface. `collider`
    is ("sphere", centre, radius) or ("plane", point, unit normal)."""
    kind, at, size = collider
    d = x - np.asarray(at, float)
    if kind == "sphere":
        return np.maximum(size - np.linalg.norm(d, axis=-1), 0.0)
    return np.maximum(-(d @ np.asarray(size, float)), 0.0)


def penetration(frames, colliders):
    """{name: (deepest depth over all frames and vertices (m), its frame, the deepest in the
    last frame (m))} per collider."""
    out = {}
    for name, c in colliders.items():
        per_frame = collider_depth(frames, c).max(axis=1)
        k = int(np.argmax(per_frame))
        out[name] = (float(per_frame[k]), k, float(per_frame[-1]))
    return out


# ---------------------------------------------------------------- triangle intersections

def _orient(a, b, c, d):
    """Six times the signed volume of (a, b, c, d), vectorised over leading axes."""
    return np.einsum("...i,...i->...", np.cross(b - a, c - a), d - a)


def _segments_cross_triangles(p, q, a, b, c):
    """Does segment pq cross triangle abc (its ends strictly on opposite sides of the plane,
    the line through the triangle or its boundary)?"""
    dp, dq = _orient(a, b, c, p), _orient(a, b, c, q)
    s1, s2, s3 = _orient(p, q, a, b), _orient(p, q, b, c), _orient(p, q, c, a)
    inside = ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))
    return (dp * dq < 0) & inside


def _cross2(u, v):
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _coplanar_overlap(T, U):
    """2D overlap of coplanar triangle pairs T, U (m, 3, 3): some edges cross properly, or a
    vertex of one lies strictly inside the other."""
    normal = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    drop = np.argmax(np.abs(normal), axis=1)
    keep = np.array([[1, 2], [0, 2], [0, 1]])[drop]
    t = np.take_along_axis(T, keep[:, None, :], axis=2)
    u = np.take_along_axis(U, keep[:, None, :], axis=2)
    hit = np.zeros(len(T), bool)
    for i in range(3):
        p, q = t[:, i], t[:, (i + 1) % 3]
        for j in range(3):
            r, s = u[:, j], u[:, (j + 1) % 3]
            d1, d2 = _cross2(q - p, r - p), _cross2(q - p, s - p)
            d3, d4 = _cross2(s - r, p - r), _cross2(s - r, q - r)
            hit |= (d1 * d2 < 0) & (d3 * d4 < 0)
    for A, B in ((t, u), (u, t)):
        for i in range(3):
            w = [_cross2(B[:, (k + 1) % 3] - B[:, k], A[:, i] - B[:, k]) for k in range(3)]
            hit |= ((w[0] > 0) & (w[1] > 0) & (w[2] > 0)) | ((w[0] < 0) & (w[1] < 0) & (w[2] < 0))
    return hit


def triangles_intersect(T, U):
    """For triangle pairs T, U (m, 3, 3): do they intersect? Two triangles not in one plane
    intersect iff an edge of one crosses the other; coplanar pairs are tested in 2D."""
    hit = np.zeros(len(T), bool)
    for A, B in ((T, U), (U, T)):
        for i in range(3):
            hit |= _segments_cross_triangles(A[:, i], A[:, (i + 1) % 3], B[:, 0], B[:, 1], B[:, 2])
    side = np.stack([_orient(U[:, 0], U[:, 1], U[:, 2], T[:, i]) for i in range(3)], 1)
    coplanar = np.all(side == 0.0, axis=1)
    if coplanar.any():
        hit[coplanar] |= _coplanar_overlap(T[coplanar], U[coplanar])
    return hit


def candidate_pairs(x, triangles):
    """Triangle pairs (i < j) whose bounding boxes overlap and that share no vertex: a uniform
    grid of cells as large as the largest box, each triangle entered in every cell it covers."""
    tri = x[triangles]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    cell = max(float((hi - lo).max()), 1e-9)
    clo, chi = np.floor(lo / cell).astype(np.int64), np.floor(hi / cell).astype(np.int64)
    ids, keys = [], []
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                c = clo + (dx, dy, dz)
                ok = np.all(c <= chi, axis=1)
                ids.append(np.nonzero(ok)[0])
                c = c[ok] - clo.min(axis=0)
                keys.append((c[:, 0] * 2**21 + c[:, 1]) * 2**21 + c[:, 2])
    ids, keys = np.concatenate(ids), np.concatenate(keys)
    order = np.lexsort((ids, keys))
    ids, keys = ids[order], keys[order]
    pairs = []
    for off in range(1, len(ids)):
        same = keys[:-off] == keys[off:]
        if not same.any():
            break
        pairs.append(np.stack([ids[:-off][same], ids[off:][same]], 1))
    if not pairs:
        return np.zeros((0, 2), np.int64)
    pairs = np.unique(np.sort(np.concatenate(pairs), axis=1), axis=0)
    i, j = pairs[:, 0], pairs[:, 1]
    overlap = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    ti, tj = triangles[i], triangles[j]
    shared = (ti[:, :, None] == tj[:, None, :]).any(axis=(1, 2))
    return pairs[overlap & ~shared]


def intersecting_pairs(x, triangles):
    """The pairs (k, 2) of triangles that share no vertex and intersect, at positions x."""
    pairs = candidate_pairs(x, triangles)
    tri = x[triangles]
    hit = triangles_intersect(tri[pairs[:, 0]], tri[pairs[:, 1]])
    return pairs[hit]


# ---------------------------------------------------------------- all of it

def run_metrics(out_dir, triangles, colliders=None, heights_at=(15, 30)):
    """Every figure of one run directory: times, strain, penetration, intersections at the end,
    and the mean height (y) after the frames in `heights_at`, a check on the motion."""
    frames = load_frames(out_dir)
    wall = wall_times(out_dir)
    smax, srms = extension_strain(frames, mesh_edges(triangles))
    row = {"frames": len(frames) - 1, "time_per_frame_s": float(wall.mean()),
           "time_per_frame_median_s": float(np.median(wall))}
    row.update(strain_summary(smax, srms))
    for name, (depth, frame, end) in penetration(frames, colliders or {}).items():
        row[f"penetration_{name}_m"], row[f"penetration_{name}_frame"] = depth, frame
        row[f"penetration_{name}_end_m"] = end
    row["intersecting_pairs_end"] = int(len(intersecting_pairs(frames[-1], triangles)))
    for k in heights_at:
        if k < len(frames):
            row[f"mean_height_{k}"] = float(frames[k, :, 1].mean())
    row["exploded"] = bool(not np.isfinite(frames[-1]).all() or np.abs(frames[-1]).max() > 100)
    return row


def self_test():
    """The intersection test on pairs with a known answer; raises AssertionError if wrong."""
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    cases = {
        "crossing": (np.array([[0.2, 0.2, -1], [0.2, 0.2, 1], [2, 2, 0.5]], float), True),
        "separate (above)": (flat + [0, 0, 0.01], False),
        "separate (beside, same plane)": (flat + [2, 0, 0], False),
        "edge through the middle": (np.array([[0.3, -1, 0.2], [0.3, 2, 0.2], [0.3, 0.5, -0.5]]),
                                    True),
        "coplanar overlap": (flat + [0.1, 0.1, 0], True),
        "close but apart": (np.array([[1.01, 0.5, -1], [1.01, 0.5, 1], [3, 0.5, 0]]), False),
    }
    for name, (tri, want) in cases.items():
        got = bool(triangles_intersect(flat[None], tri[None])[0])
        back = bool(triangles_intersect(tri[None], flat[None])[0])
        assert got == want and back == want, f"{name}: got {got}/{back}, want {want}"
    # A mesh: a flat 3 x 3 grid and a strip pushed through its middle, and the same strip
    # lifted clear of it; pairs sharing a vertex (every neighbour in the grid) never count.
    x = np.array([[i, j, 0] for j in range(3) for i in range(3)]
                 + [[1.2, 0.5, -1], [1.2, 0.5, 1], [1.3, 1.5, 0.5]], float)
    tris = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [3, 4, 7], [3, 7, 6],
                     [4, 5, 8], [4, 8, 7], [9, 10, 11]])
    assert len(intersecting_pairs(x, tris)) > 0, "a strip through the grid must intersect it"
    x[9:, 2] += 3.0
    assert len(intersecting_pairs(x, tris)) == 0, "a strip above the grid must not"
    return len(cases) + 2


if __name__ == "__main__":
    if sys.argv[1:] == ["--self-test"]:
        print(f"cloth_metrics self-test: {self_test()} cases passed")
    else:
        sys.exit("usage: cloth_metrics.py --self-test (import it for the metrics)")
