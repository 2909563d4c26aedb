#!/usr/bin/env python3
"""How a drape run moves, beside its strain: strain alone rewards a cloth held up.

usage: bench/motion.py RUN_DIR [REFERENCE_DIR]

Reads the frame_NNNN.obj files `nucleus run --out DIR` writes and prints the lowest point any
frame reached (m), the particles' mean height (their centre of mass in the drape, where every
particle weighs the same) after frames 15, 30, 60 and the last; with a reference run of the
same scene and resolution, the largest difference of that mean height over the frames and the
RMS distance between the two runs' particles, averaged over all frames and over the first 30
(before the swinging cloth's folds, which diverge between any two solvers, dominate it).

With the run's stats.csv (`nucleus run --out` writes it) it prints the energy too: kinetic plus
potential (gravity and the springs' stored energy, the `kinetic_j` and `potential_j` columns,
from the solver's own velocities) at the end, and its largest rise above the lowest value
reached before (J). The drape has no damping and no energy source: a solver may lose energy
(implicit Euler and PBD do), but a rise is energy it made. The plain `stretch` reference rises by
0.01–0.08 J, from rounding and the start; an unconverged Newton setting can rise by joules and
throw the cloth up late in a run that looked right for 30 frames.
"""
import os
import sys

import numpy as np

from drape_metrics import energies, largest_rise, read_obj_vertices


def load(d):
    """The vertices (n x 3) of every frame_*.obj in `d`, in frame order."""
    names = sorted(f for f in os.listdir(d) if f.startswith("frame_") and f.endswith(".obj"))
    return [np.array(read_obj_vertices(os.path.join(d, f))).reshape(-1, 3) for f in names]


def energy(d):
    """Kinetic plus potential energy (J) after each frame, from `d`/stats.csv (None if absent)."""
    if not os.path.exists(os.path.join(d, "stats.csv")):
        return None
    e = energies(d)
    return None if e is None else np.array(e)


def main():
    a = load(sys.argv[1])
    height = np.array([x[:, 1].mean() for x in a])
    lowest = min(x[:, 1].min() for x in a)
    frames = [k for k in (15, 30, 60, len(a) - 1) if k < len(a)]
    msg = f"lowest {lowest:.3f} m; mean height after frames " + "/".join(
        str(k) for k in frames) + ": " + "/".join(f"{height[k]:.3f}" for k in frames) + " m"
    if len(sys.argv) > 2:
        b = load(sys.argv[2])
        n = min(len(a), len(b))
        href = np.array([x[:, 1].mean() for x in b[:n]])
        dist = [np.sqrt(((a[k] - b[k]) ** 2).sum(1).mean()) for k in range(n)]
        msg += (f"; vs reference: mean height off by {np.abs(height[:n] - href).max():.3f} m at "
                f"most, RMS distance {np.mean(dist):.3f} m (first 30 frames {np.mean(dist[:30]):.3f})")
    e = energy(sys.argv[1])
    if e is not None and len(e):
        rise, at = largest_rise(list(e))
        msg += f"; energy at the end {e[-1]:+.3f} J, largest rise {rise:.3f} J (frame {at + 1})"
    print(msg)


if __name__ == "__main__":
    main()
