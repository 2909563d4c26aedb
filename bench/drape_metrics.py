#!/usr/bin/env python3
"""The peers' "drape" metrics (../shared/peers/common.py), computed from a `nucleus run` output.

usage: drape_metrics.py OUT_DIR --N N [--frames 120] [--window 60] [key=value ...]

Reads OUT_DIR/frame_NNNN.obj (the `v x y z` lines, in particle order; frame 0 is the initial
state, frame k the state after k frames), OUT_DIR/stats.csv (`wall_s` = step time of each frame)
and OUT_DIR/run.json, and prints one JSON line with the same fields as the peers' scripts:

* time_per_frame_s: mean step wall time of frames 2..F (frame 1 is `first_frame_s`);
  time_per_frame_median_s likewise;
* strain over the 2N(N-1) structural (grid-aligned) edges (i,j)-(i,j+1) and (i,j)-(i+1,j), where
  vertex (i, j) has index i*N + j: |l - l0| / l0 per edge, per frame its max and RMS, averaged over
  the last `window` frames (F-window+1..F) -> strain_max, strain_rms; the largest per-frame max
  -> strain_max_peak; the mean over the same frames of the max strain of the diagonals
  (i,j)-(i+1,j+1) -> diag_strain_max;
* where the max sits: per frame, the grid distance (Chebyshev, in edges) of the max-strain
  edge from the nearer pinned corner -> strain_max_ring_median (its median over the window)
  and strain_max_near_pin_share (the share of frames with the max within 2 edges of a pin);
* min_height: lowest y at frame F; exploded: NaN anywhere or |x| > 100 m at frame F;
* mean_height_15, mean_height_30: the particles' mean y after frames 15 and 30 (0.25 s and 0.5 s
  at 60 fps; null for a shorter run) — the motion, which strain alone does not see: a solver
  that holds the cloth up can have little strain. Plain `stretch` at 320 substeps gives about
  -0.24 and -0.49 m at N = 32 to 128 (bench/motion.py compares whole runs);
* energy_rise_j: from stats.csv's `kinetic_j` and `potential_j` (gravity and the springs), the
  largest rise of their sum above the lowest value reached before, over frames 1..F (J; null if
  the columns are missing). The drape has no damping and no source, so a rise is energy the
  solver made: plain `stretch` rises by 0.01-0.08 J, an unconverged Newton setting by joules
  (bench/motion.py prints the same figure); energy_end_j: that sum after frame F (J; it starts
  at 0, the flat cloth at rest at y = 0). Below the reference's end it is energy damped out: the
  `tether` run at 640 x 1 ends at -1.24 J at N = 128, implicit Euler at 2 substeps near -2.3 J.

Rest lengths come from frame 0. `key=value` arguments are copied into the JSON line (numbers
parsed). Pure Python; numpy is used when it is importable (about 20x faster at N = 128).
"""

import argparse
import json
import math
import os
import sys

try:
    import numpy as np
except ImportError:  # the test suite and this script never need numpy
    np = None


def read_obj_vertices(path):
    """The `v` lines of an OBJ as a flat list of floats [x0, y0, z0, x1, ...]."""
    out = []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                _, x, y, z = line.split()[:4]
                out.append(float(x))
                out.append(float(y))
                out.append(float(z))
    return out


def edges(N):
    struct, diag = [], []
    for i in range(N):
        for j in range(N):
            if j + 1 < N:
                struct.append((i * N + j, i * N + j + 1))
            if i + 1 < N:
                struct.append((i * N + j, (i + 1) * N + j))
            if i + 1 < N and j + 1 < N:
                diag.append((i * N + j, (i + 1) * N + j + 1))
    return struct, diag


class Strain:
    """|l - l0| / l0 over a fixed edge list: per-frame max and RMS."""

    def __init__(self, rest, pairs):
        self.pairs = pairs
        if np is not None:
            self.a = np.array([p[0] for p in pairs])
            self.b = np.array([p[1] for p in pairs])
            x = np.asarray(rest).reshape(-1, 3)
            self.l0 = np.linalg.norm(x[self.a] - x[self.b], axis=1)
        else:
            self.l0 = [self._length(rest, a, b) for a, b in pairs]

    @staticmethod
    def _length(x, a, b):
        dx = x[3 * a] - x[3 * b]
        dy = x[3 * a + 1] - x[3 * b + 1]
        dz = x[3 * a + 2] - x[3 * b + 2]
        return math.sqrt(dx * dx + dy * dy + dz * dz)

    def frame(self, x):
        """(max, rms) of the strain at positions x (flat list)."""
        mx, rms, _ = self.frame_at(x)
        return mx, rms

    def frame_at(self, x):
        """(max, rms, the edge (a, b) with the max strain) at positions x (flat list)."""
        if np is not None:
            p = np.asarray(x).reshape(-1, 3)
            s = np.abs(np.linalg.norm(p[self.a] - p[self.b], axis=1) - self.l0) / self.l0
            k = int(np.argmax(s))
            return float(s[k]), float(np.sqrt(np.mean(s * s))), self.pairs[k]
        mx, sq, at = -1.0, 0.0, None
        for (a, b), l0 in zip(self.pairs, self.l0):
            s = abs(self._length(x, a, b) - l0) / l0
            if s > mx:
                mx, at = s, (a, b)
            sq += s * s
        return mx, math.sqrt(sq / len(self.pairs)), at


def ring_from_pins(N, a, b):
    """How many grid steps (Chebyshev distance) the nearer end of edge (a, b) lies from the
    nearer pinned corner, (0, 0) or (0, N-1): 0 for the edges at a pin."""
    def ring(v):
        i, j = divmod(v, N)
        return min(max(i, j), max(i, N - 1 - j))
    return min(ring(a), ring(b))


def mean(xs):
    return sum(xs) / len(xs) if xs else None


def median(xs):
    s = sorted(xs)
    n = len(s)
    if n == 0:
        return None
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def wall_times(out_dir):
    """wall_s of frames 1..F from stats.csv, in frame order."""
    with open(os.path.join(out_dir, "stats.csv")) as f:
        header = f.readline().strip().split(",")
        fi, wi = header.index("frame"), header.index("wall_s")
        rows = [line.strip().split(",") for line in f if line.strip()]
    return [float(r[wi]) for r in sorted(rows, key=lambda r: int(r[fi]))]


def energies(out_dir, frames=None):
    """Kinetic + potential energy (J) after each of frames 1..`frames` (all if None), from
    stats.csv's `kinetic_j` and `potential_j`; None without those columns."""
    with open(os.path.join(out_dir, "stats.csv")) as f:
        header = f.readline().strip().split(",")
        if "kinetic_j" not in header or "potential_j" not in header:
            return None
        fi, ki, pi = header.index("frame"), header.index("kinetic_j"), header.index("potential_j")
        rows = [line.strip().split(",") for line in f if line.strip()]
    return [float(r[ki]) + float(r[pi]) for r in sorted(rows, key=lambda r: int(r[fi]))][:frames]


def largest_rise(energy):
    """The largest rise of `energy` above its lowest value so far, and the index where it is
    reached (the first such); (0.0, 0) for a sequence that never rises."""
    lowest, rise, at = energy[0], 0.0, 0
    for k, e in enumerate(energy):
        lowest = min(lowest, e)
        if e - lowest > rise:
            rise, at = e - lowest, k
    return rise, at


def energy_rise(out_dir, frames):
    """The largest rise of kinetic + potential energy above its lowest value so far (J), over
    frames 1..`frames` of stats.csv, and that energy after the last of them; (None, None)
    without the energy columns or with a non-finite value."""
    energy = energies(out_dir, frames)
    if not energy or not all(math.isfinite(e) for e in energy):
        return None, None
    return largest_rise(energy)[0], energy[-1]


def metrics(out_dir, N, frames, window):
    run = {}
    run_json = os.path.join(out_dir, "run.json")
    if os.path.exists(run_json):
        with open(run_json) as f:
            run = json.load(f)
    if run.get("status") != "complete":
        return {"error": run.get("error", "run incomplete (no complete run.json)")}
    times = wall_times(out_dir)
    if len(times) < frames:
        return {"error": f"stats.csv has {len(times)} frames, expected {frames}"}
    times = times[:frames]
    rest = read_obj_vertices(os.path.join(out_dir, "frame_0000.obj"))
    if len(rest) != 3 * N * N:
        return {"error": f"frame 0 has {len(rest) // 3} vertices, expected N*N = {N * N}"}
    struct, diag = edges(N)
    s_struct, s_diag = Strain(rest, struct), Strain(rest, diag)
    window = min(window, frames)
    maxs, rmss, dmaxs, rings = [], [], [], []
    last = None
    for k in range(frames - window + 1, frames + 1):
        x = read_obj_vertices(os.path.join(out_dir, f"frame_{k:04d}.obj"))
        mx, rms, at = s_struct.frame_at(x)
        rings.append(ring_from_pins(N, *at))
        maxs.append(mx)
        rmss.append(rms)
        dmaxs.append(s_diag.frame(x)[0])
        last = x
    finite = all(math.isfinite(c) for c in last)

    def mean_height(k):
        if k > frames:
            return None
        ys = read_obj_vertices(os.path.join(out_dir, f"frame_{k:04d}.obj"))[1::3]
        return clean(sum(ys) / len(ys))

    steady = times[1:] if len(times) > 1 else times
    rise, energy_end = energy_rise(out_dir, frames)

    def clean(v):
        return v if v is not None and math.isfinite(v) else None

    return {
        "frames": frames,
        "first_frame_s": round(times[0], 5),
        "time_per_frame_s": mean(steady),
        "time_per_frame_median_s": median(steady),
        "strain_max": clean(mean(maxs)),
        "strain_rms": clean(mean(rmss)),
        "strain_max_peak": clean(max(maxs)),
        "diag_strain_max": clean(mean(dmaxs)),
        "strain_max_ring_median": median(rings),
        "strain_max_near_pin_share": sum(1 for r in rings if r <= 2) / len(rings),
        "min_height": clean(min(last[1::3])),
        "mean_height_15": mean_height(15),
        "mean_height_30": mean_height(30),
        "energy_rise_j": rise,
        "energy_end_j": energy_end,
        "exploded": (not finite) or max(abs(c) for c in last) > 100.0,
    }


def parse_value(v):
    for conv in (int, float):
        try:
            return conv(v)
        except ValueError:
            pass
    return v


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out_dir")
    p.add_argument("--N", type=int, required=True, help="vertices per side")
    p.add_argument("--frames", type=int, default=120)
    p.add_argument("--window", type=int, default=60)
    p.add_argument("extra", nargs="*", help="key=value copied into the JSON line")
    a = p.parse_intermixed_args()
    res = {}
    for kv in a.extra:
        k, _, v = kv.partition("=")
        res[k] = parse_value(v)
    res["N"] = a.N
    res.update(metrics(a.out_dir, a.N, a.frames, a.window))
    print(json.dumps(res), flush=True)
    return 0 if "error" not in res else 1


if __name__ == "__main__":
    sys.exit(main())
