#!/usr/bin/env python3
"""Time against strain on the drape, every solver of one N, as an SVG (Python standard library).

usage: front_plot.py DOC --N N [--out FILE.svg] [--budget-ms 16] [--rms 0.001] [--max 0.01]

Reads a doc written by `bench/peers.py` (`docs/peers.md`, `docs/peers_2threads.md`): every run
of ours from its "Every run of ours" table, and the peers' Pareto points from its "Pareto
fronts" tables (the doc keeps only those of theirs). Draws two log-log panels, the RMS strain
and the max strain (the structural edges, means over the last 60 frames, as the doc) against
the mean step time per frame: one colour per solver and thread count, a dot per run, a line
through its Pareto front (the runs no faster run beats on that strain; a run of ours whose
motion fails `motion_flag`'s checks is a hollow dot, left off the front), and the benchmark
issue's target as a shaded box (within `--budget-ms`, at most `--rms` RMS / `--max` max
strain). `bench/peers.py` calls `plot` itself for every N it writes a doc for.
"""

import argparse
import math
import os
import re
import sys

# Colour-blind-safe palette (Okabe and Ito, then two more), ours first, then the peers' (whose
# lines are dashed).
COLOURS = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#999999",
           "#8B4513"]
PANEL_W, PANEL_H = 420, 320
# Motion checks, since strain alone rewards a cloth held up (bench/motion.py). The drape's
# particles' mean height after 0.5 s is -0.487 to -0.497 m for the converged solvers of ours at
# N = 32 to 128 (plain `stretch` 320 x 2, `tether` 640 x 1, `stretch_newton` 2 x 3 x 5); higher
# by more than HELD_UP_M is a cloth held up. The drape has no source of energy; a rise of more
# than ENERGY_RISE_J (a fifth of the 4.9 J its fall of half a metre releases) is energy the
# solver made.
MEAN_HEIGHT_30_M = -0.49
HELD_UP_M = 0.05
ENERGY_RISE_J = 1.0
LEFT, TOP, GAP = 70, 40, 90


def motion_flag(r):
    """What is wrong with a run's motion ("held up", "makes energy"), or "" if nothing we check
    is: from its `flag` (a doc's motion column) or its `mean_height_30` and `energy_rise_j`.
    The peers' rows carry neither figure and are never flagged."""
    if "flag" in r:
        return r["flag"]
    flags = []
    h = r.get("mean_height_30")
    if h is not None and h > MEAN_HEIGHT_30_M + HELD_UP_M:
        flags.append("held up")
    e = r.get("energy_rise_j")
    if e is not None and e > ENERGY_RISE_J:
        flags.append("makes energy")
    return ", ".join(flags)


def parse_doc(path):
    """The runs of a peers doc: dicts with solver, N, threads, substeps, iters,
    time_per_frame_s, strain_max, strain_rms."""
    rows, section, n = [], None, None
    with open(path) as f:
        for line in f:
            line = line.rstrip("\n")
            if line.startswith("## "):
                section = line[3:]
                continue
            m = re.match(r"### N = (\d+)", line)
            if m:
                n = int(m.group(1))
                continue
            if not line.startswith("| ") or line.startswith("| solver") or "---" in line:
                continue
            cells = [c.strip() for c in line.strip("|").split("|")]
            try:
                if section == "Every run of ours" and len(cells) >= 7:
                    solver, N, th, setting, ms, smax, srms = cells[:7]
                    N = int(N)
                elif section and section.startswith("Pareto fronts") and len(cells) >= 6:
                    solver, th, setting, ms, smax, srms = cells[:6]
                    if solver.startswith("nucleus"):
                        continue  # every run of ours is in the other table
                    N = n
                else:
                    continue
                s, i = (int(x) for x in setting.split("x"))
                rows.append({"solver": solver, "N": N, "threads": int(th), "substeps": s, "iters": i,
                             "time_per_frame_s": float(ms) / 1e3, "strain_max": float(smax),
                             "strain_rms": float(srms)})
                if section == "Every run of ours" and len(cells) >= 12:
                    rows[-1]["flag"] = cells[11]  # the motion column (older docs have none)
            except ValueError:
                continue  # an error row, or a cell that is not a number
    return rows


def pareto(runs, metric):
    """The runs no faster run beats on `metric`, fastest first."""
    front, best = [], math.inf
    for r in sorted(runs, key=lambda r: (r["time_per_frame_s"], r[metric])):
        if r[metric] < best:
            best = r[metric]
            front.append(r)
    return front


def decades(lo, hi):
    return list(range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1))


def fmt_decade(e, unit):
    v = 10.0 ** e
    if unit == "%":
        v *= 100
    s = f"{v:g}" if 1e-3 <= v < 1e4 else f"1e{e + (2 if unit == '%' else 0)}"
    return s + (" %" if unit == "%" else "")


def plot(rows, N, budget_ms=16.0, rms=0.001, mx=0.01, title=None, peers_pareto_only=False):
    """The SVG text: RMS and max strain against ms a frame for the runs at `N` (`None` for
    none); `peers_pareto_only` says in the legend that the peers' rows are their Pareto points
    only (as a doc keeps them)."""
    runs = [r for r in rows if r.get("N") == N and r.get("time_per_frame_s") and r.get("strain_rms")
            and r.get("strain_max") and not r.get("exploded")]
    if not runs:
        return None
    groups = {}
    for r in runs:
        groups.setdefault((r["solver"], r.get("threads", 1)), []).append(r)
    keys = sorted(groups, key=lambda k: (not k[0].startswith("nucleus"), k[0], k[1]))
    colour = {k: COLOURS[i % len(COLOURS)] for i, k in enumerate(keys)}

    def dash(k):
        return "" if k[0].startswith("nucleus") else ' stroke-dasharray="6,3"'

    ms = [r["time_per_frame_s"] * 1e3 for r in runs] + [budget_ms]
    xd = decades(min(ms), max(ms))
    width = LEFT + 2 * PANEL_W + GAP + 30
    height = TOP + PANEL_H + 62 + 18 * ((len(keys) + 1) // 2)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{width}" height="{height}" fill="white"/>',
           f'<text x="{width / 2}" y="20" text-anchor="middle" font-size="14">'
           f'{title or f"The drape at N = {N}: strain against time per frame"}</text>']
    for p, (metric, target, name) in enumerate([("strain_rms", rms, "RMS strain"),
                                                ("strain_max", mx, "max strain")]):
        x0 = LEFT + p * (PANEL_W + GAP)
        vals = [r[metric] for r in runs] + [target]
        yd = decades(min(vals), max(vals))

        def X(v):
            return x0 + (math.log10(v) - xd[0]) / (xd[-1] - xd[0]) * PANEL_W

        def Y(v):
            return TOP + PANEL_H - (math.log10(v) - yd[0]) / (yd[-1] - yd[0]) * PANEL_H

        out.append(f'<rect x="{X(10.0 ** xd[0]):.1f}" y="{Y(target):.1f}" '
                   f'width="{X(budget_ms) - X(10.0 ** xd[0]):.1f}" height="{Y(10.0 ** yd[0]) - Y(target):.1f}" '
                   f'fill="#2ca02c" fill-opacity="0.12" stroke="#2ca02c" stroke-dasharray="4,3"/>')
        out.append(f'<text x="{X(10.0 ** xd[0]) + 4:.1f}" y="{Y(10.0 ** yd[0]) - 6:.1f}" fill="#2ca02c">'
                   f'target: within {budget_ms:g} ms, {name} at most {target * 100:g} %</text>')
        for e in xd:
            x = X(10.0 ** e)
            out.append(f'<line x1="{x:.1f}" y1="{TOP}" x2="{x:.1f}" y2="{TOP + PANEL_H}" stroke="#ddd"/>')
            out.append(f'<text x="{x:.1f}" y="{TOP + PANEL_H + 16}" text-anchor="middle">{fmt_decade(e, "")}</text>')
        for e in yd:
            y = Y(10.0 ** e)
            out.append(f'<line x1="{x0}" y1="{y:.1f}" x2="{x0 + PANEL_W}" y2="{y:.1f}" stroke="#ddd"/>')
            out.append(f'<text x="{x0 - 6}" y="{y + 4:.1f}" text-anchor="end">{fmt_decade(e, "%")}</text>')
        out.append(f'<rect x="{x0}" y="{TOP}" width="{PANEL_W}" height="{PANEL_H}" fill="none" stroke="#444"/>')
        out.append(f'<text x="{x0 + PANEL_W / 2}" y="{TOP + PANEL_H + 34}" text-anchor="middle">'
                   f'ms per frame (log)</text>')
        out.append(f'<text x="{x0 - 52}" y="{TOP + PANEL_H / 2}" text-anchor="middle" '
                   f'transform="rotate(-90 {x0 - 52} {TOP + PANEL_H / 2})">{name} (log)</text>')
        for k in keys:
            c = colour[k]
            for r in groups[k]:
                flag = motion_flag(r)
                fill = f'fill="white" stroke="{c}"' if flag else f'fill="{c}" fill-opacity="0.45"'
                out.append(f'<circle cx="{X(r["time_per_frame_s"] * 1e3):.1f}" cy="{Y(r[metric]):.1f}" r="2.5" '
                           f'{fill}><title>{k[0]}, {k[1]} thread(s), '
                           f'{r["substeps"]} x {r["iters"]}: {r["time_per_frame_s"] * 1e3:.3g} ms, '
                           f'{name} {r[metric] * 100:.3g} %{f" ({flag})" if flag else ""}</title></circle>')
            # The front runs through the runs whose motion passes the checks (hollow dots: not).
            front = pareto([r for r in groups[k] if not motion_flag(r)], metric)
            if len(front) < 2:
                continue
            pts = " ".join(f'{X(r["time_per_frame_s"] * 1e3):.1f},{Y(r[metric]):.1f}' for r in front)
            out.append(f'<polyline points="{pts}" fill="none" stroke="{c}" stroke-width="1.8"{dash(k)}/>')
    for i, k in enumerate(keys):
        x = LEFT + (i % 2) * (PANEL_W + GAP)
        y = TOP + PANEL_H + 62 + 18 * (i // 2)
        out.append(f'<line x1="{x}" y1="{y - 4}" x2="{x + 22}" y2="{y - 4}" stroke="{colour[k]}" '
                   f'stroke-width="2"{dash(k)}/>')
        out.append(f'<text x="{x + 28}" y="{y}">{k[0]}, {k[1]} thread{"s" if k[1] != 1 else ""}'
                   f'{" (Pareto points only)" if peers_pareto_only and not k[0].startswith("nucleus") else ""}'
                   '</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("doc")
    p.add_argument("--N", type=int, required=True)
    p.add_argument("--out", default=None, help="SVG file [default: the doc's name with _N<N>.svg]")
    p.add_argument("--budget-ms", type=float, default=16.0)
    p.add_argument("--rms", type=float, default=0.001)
    p.add_argument("--max", type=float, default=0.01)
    a = p.parse_args()
    with open(a.doc) as f:
        when = re.search(r"Generated by `bench/peers.sh` on ([0-9-]+)", f.read())
    title = (f"The drape at N = {a.N}: strain against time per frame "
             f"({os.path.basename(a.doc)}{', ' + when.group(1) if when else ''})")
    text = plot(parse_doc(a.doc), a.N, a.budget_ms, a.rms, a.max, title, peers_pareto_only=True)
    if text is None:
        sys.exit(f"{a.doc}: no run at N = {a.N}")
    out = a.out or re.sub(r"\.md$", "", a.doc) + f"_N{a.N}.svg"
    with open(out, "w") as f:
        f.write(text)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
