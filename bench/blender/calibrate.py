#!/usr/bin/env python3
"""Which stretch stiffness Blender can solve: the drape at several tensions against our fall.

usage: calibrate.py [--tensions 100,200,400,700,1000] [--N 64] [--frames 30] [--mass 0.3]

Runs Blender (blender_run.py, 1 thread) on scenes/drape.toml at each `--tension`, and ours on
the same scene at 320 substeps (hard `stretch`, converged: the fall every solver should match)
as the reference, and prints per run: the mean height after 15 and 30 frames, the max and RMS
extension strain at the last frame, and the frames whose CG stopped at 100 iterations
unconverged. The stiffest tension whose fall stays with the reference is the one
compare.py uses (bench/blender/README.md records the scan).
"""

import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tensions", default="100,200,400,700,1000")
    p.add_argument("--N", type=int, default=64)
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--mass", type=float, default=0.3)
    c = p.parse_args()
    sets = [] if c.N == 64 else [f"objects.0.grid.resolution=[{c.N},{c.N}]"]
    base = ["--frames", str(c.frames), "--mass", str(c.mass), "--rounds", "1",
            "--work", os.path.join(compare.ROOT, "target", "blender-calibrate")]
    print("| solver | tension | mean height 15 (m) | mean height 30 (m) | end max / RMS strain "
          "| unconverged frames | ms / frame |\n|---|---:|---:|---:|---:|---:|---:|")
    rows = [("ours (stretch, 320 substeps)", "–", compare.run_one(
        compare.parse_args(base), "ours", "drape", c.N, sets, 0, ["--substeps", "320"]))]
    for t in c.tensions.split(","):
        a = compare.parse_args(base + ["--tension", t])
        rows.append(("blender", t, compare.run_one(a, "blender", "drape", c.N, sets, 0)))
    for name, t, r in rows:
        print(f"| {name} | {t} | {r['mean_height_15']:.4f} | {r['mean_height_30']:.4f} | "
              f"{100 * r['strain_max_end']:.2f} % / {100 * r['strain_rms_end']:.3f} % | "
              f"{r.get('cg_unconverged_frames', '–')} | {1000 * r['time_per_frame_s']:.0f} |",
              flush=True)


if __name__ == "__main__":
    main()
