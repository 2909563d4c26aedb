#!/usr/bin/env python3
"""How sure a drape figure is: one setting run K times, gravity changed by a tiny share of itself.

usage: bench/spread.py SCENE --N 128 [--runs 15] [--threads 2] [--bound 0.01] [nucleus run args ...]

The drape's folds are chaotic: changing gravity by 1e-8 of itself moves only the rounding, yet it
moves a run's max strain (the mean over the last 60 frames of each frame's largest structural
strain) by tenths of a per cent, and an unconverged setting's energy rise by its whole size
(docs/decisions/newton-relaxation.md). One run is one sample. This runs `nucleus run SCENE` with
gravity (0, -g, 0) for g in 9.81, 9.8100001, 9.8099999, 9.81001, 9.80999, ... (the first
`--runs` of `GRAVITIES`, below), and prints each run's `bench/drape_metrics.py` figures and, per figure, the
range and the runs over `--bound` (max strain) or over 1 J (energy rise, the sweep's
"makes energy" mark). Arguments after the options go to `nucleus run` unchanged (say `--substeps
1 --iterations 3 --set constraints.0.params.cg_iterations=3`). Needs the release host and
plugins (`cargo xtask plugins --release`); writes its runs under target/spread/ and removes them.

Example (the `newton_relaxed` setting):

    python3 bench/spread.py scenes/drape_newton.toml --N 128 --runs 15 -- --substeps 1 \\
        --iterations 3 --set constraints.0.params.compliance=1e-6 \\
        --set constraints.0.params.compression_compliance=1e-6 \\
        --set constraints.0.params.cg_iterations=3 --set constraints.0.params.start_passes=10 \\
        --set constraints.0.params.plain_levels=1 --set constraints.0.params.relaxation=0.7
"""

import argparse
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import drape_metrics  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# Gravity (m/s², along -y) of each run, as text: the decision records' tables used these
# fifteen, in this order (9.81 changed by 1e-8 to 5e-6 of itself); later runs go on in steps of 1e-5.
GRAVITIES = ["9.81", "9.8100001", "9.8099999", "9.81001", "9.80999", "9.80998", "9.81002",
             "9.80997", "9.81003", "9.80996", "9.81004", "9.80995", "9.81005", "9.809995",
             "9.810005"]


def gravities(runs):
    """The first `runs` gravities: GRAVITIES, then 9.81 -+ 6e-5, 7e-5, ..."""
    out = list(GRAVITIES)
    k = 6
    while len(out) < runs:
        out += [f"{9.81 - k * 1e-5:.5f}", f"{9.81 + k * 1e-5:.5f}"]
        k += 1
    return out[:runs]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("scene")
    p.add_argument("--N", type=int, required=True, help="vertices per side (the grid's resolution)")
    p.add_argument("--runs", type=int, default=15)
    p.add_argument("--threads", type=int, default=2, help="RAYON_NUM_THREADS")
    p.add_argument("--frames", type=int, default=120)
    p.add_argument("--bound", type=float, default=0.01, help="max strain bound counted against")
    p.add_argument("--nucleus", default=os.path.join(ROOT, "target", "release", "nucleus"))
    # Everything else (after `--`, or any option not above) goes to `nucleus run`.
    a, rest = p.parse_known_args()
    extra = [x for x in rest if x != "--"]
    if not os.path.exists(a.nucleus):
        sys.exit(f"{a.nucleus} not found: run `cargo xtask plugins --release` first")
    work = os.path.join(ROOT, "target", "spread")
    rows = []
    for g in gravities(a.runs):
        out = os.path.join(work, f"run{len(rows)}")
        shutil.rmtree(out, ignore_errors=True)
        cmd = [a.nucleus, "run", a.scene, "--quiet", "--frames", str(a.frames), "--out", out,
               "--set", f"objects.0.grid.resolution=[{a.N},{a.N}]",
               "--set", f"solver.gravity=[0.0,-{g},0.0]"] + extra
        env = dict(os.environ, RAYON_NUM_THREADS=str(a.threads))
        run = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if run.returncode != 0:
            shutil.rmtree(out, ignore_errors=True)
            sys.exit(f"g = {g}: nucleus run failed: {run.stderr.strip()[-400:]}")
        m = drape_metrics.metrics(out, a.N, a.frames, 60)
        shutil.rmtree(out, ignore_errors=True)
        rows.append((g, m))
        print(f"g = {g}: {m['time_per_frame_s'] * 1e3:.2f} ms/frame, max strain "
              f"{100 * m['strain_max']:.3f} %, RMS {100 * m['strain_rms']:.4f} %, energy rise "
              f"{m['energy_rise_j']:.3f} J", flush=True)
    shutil.rmtree(work, ignore_errors=True)

    def span(key, scale=1.0):
        xs = [m[key] * scale for _, m in rows if m.get(key) is not None]
        return (min(xs), max(xs)) if xs else (float("nan"), float("nan"))

    over = sum(1 for _, m in rows if m["strain_max"] > a.bound)
    energetic = sum(1 for _, m in rows if (m.get("energy_rise_j") or 0.0) > 1.0)
    lo, hi = span("strain_max", 100)
    rlo, rhi = span("strain_rms", 100)
    elo, ehi = span("energy_rise_j")
    print(f"{len(rows)} runs: max strain {lo:.2f}-{hi:.2f} % ({over} over {100 * a.bound:g} %), "
          f"RMS {rlo:.3f}-{rhi:.3f} %, energy rise {elo:.2f}-{ehi:.2f} J ({energetic} over 1 J)")


if __name__ == "__main__":
    main()
