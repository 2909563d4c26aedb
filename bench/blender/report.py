"""The tables and the page docs/blender.md of bench/blender/compare.py, from its rows.

Per case (scene, N): the median over rounds of each solver's time per frame, the ratio
ours / Blender taken within each round (median and range), and the accuracy figures of the
last round (both solvers are deterministic here; `identical over rounds` says whether every
round gave the same figures).
"""

import argparse
import statistics

# The accuracy figures compared for "equal or better", each with the tolerance under which a
# difference does not count (strain: absolute, penetration: m, pairs: count).
COMPARED = [("strain_max", 1e-4), ("strain_rms", 1e-4), ("strain_peak", 1e-4),
            ("penetration_sphere_m", 1e-4), ("penetration_ground_m", 1e-4),
            ("intersecting_pairs_end", 0)]
ACCURACY_KEYS = [k for k, _ in COMPARED] + ["share_max_within_1pct"]


def by_case(rows):
    """{(scene, N): {solver: [rows in round order]}}, cases in first-seen order."""
    out = {}
    for r in rows:
        out.setdefault((r["scene"], r["N"]), {}).setdefault(r["solver"], []).append(r)
    return out


def ratios(runs, key="time_per_frame_s"):
    """ours / Blender of `key` (a time per frame) within each round both ran."""
    blender = {r["round"]: r[key] for r in runs.get("blender", [])}
    return [r[key] / blender[r["round"]] for r in runs.get("ours", []) if r["round"] in blender]


def verdict(ours, theirs):
    """'yes', or 'no: ...' naming the figures where ours is worse than Blender's."""
    worse = [k for k, tol in COMPARED
             if k in ours and k in theirs and ours[k] > theirs[k] + tol]
    return "yes" if not worse else "no: " + ", ".join(NAMES.get(k, k) for k in worse)


NAMES = {"strain_max": "max strain", "strain_rms": "RMS strain", "strain_peak": "peak strain",
         "penetration_sphere_m": "sphere penetration", "penetration_ground_m":
         "ground penetration", "intersecting_pairs_end": "intersections"}


def pct(x):
    return f"{100 * x:.2f} %"


def ms(x):
    """Seconds as milliseconds to about three significant digits."""
    v = 1000 * x
    return f"{v:.0f}" if v >= 100 else f"{v:.1f}" if v >= 10 else f"{v:.2f}"


def ratio_fmt(x):
    return f"{x:.2f}" if x >= 0.1 else f"{x:.4f}"


def spread(xs, fmt):
    return fmt(statistics.median(xs)) + (f" ({fmt(min(xs))}–{fmt(max(xs))})" if len(xs) > 1 else "")


def penetration_cell(r, suffix="m"):
    parts = [f"{name} {1000 * r[f'penetration_{name}_{suffix}']:.2f}"
             for name in ("sphere", "ground") if f"penetration_{name}_{suffix}" in r]
    return ", ".join(parts) if parts else "–"


def identical(runs):
    first = {k: runs[0].get(k) for k in ACCURACY_KEYS}
    return all({k: r.get(k) for k in ACCURACY_KEYS} == first for r in runs)


def table(rows):
    """The main table: two lines per case, ours then Blender."""
    out = ["| scene | N | solver | ms / frame | CPU ms / frame | max strain | RMS strain | "
           "peak strain (frame) | frames max ≤ 1 % | penetration (mm) | intersecting pairs "
           "at end | time ours / Blender | CPU ours / Blender | equal or better accuracy? |",
           "|---|---:|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---|"]
    for (scene, n), runs in by_case(rows).items():
        last = {s: rs[-1] for s, rs in runs.items()}
        for solver in ("ours", "blender"):
            if solver not in runs:
                continue
            r, rs = last[solver], runs[solver]
            ratio = cpu_ratio = verdict_cell = ""
            if solver == "ours" and "blender" in runs:
                ratio = spread(ratios(runs), ratio_fmt)
                cpu_ratio = spread(ratios(runs, "cpu_per_frame_s"), ratio_fmt)
                verdict_cell = verdict(r, last["blender"])
            out.append(
                f"| {scene} | {n} | {'Nucleus' if solver == 'ours' else 'Blender'} | "
                f"{spread([x['time_per_frame_s'] for x in rs], ms)} | "
                f"{spread([x['cpu_per_frame_s'] for x in rs], ms)} | {pct(r['strain_max'])} | "
                f"{pct(r['strain_rms'])} | {pct(r['strain_peak'])} ({r['strain_peak_frame']}) | "
                f"{100 * r['share_max_within_1pct']:.0f} % | {penetration_cell(r)} | "
                f"{r['intersecting_pairs_end']} | {ratio} | {cpu_ratio} | {verdict_cell} |")
    return "\n".join(out)


def motion_table(rows):
    """Mean heights after 15 and 30 frames (the fall), Blender's unconverged frames, and
    whether every round gave the same accuracy figures."""
    out = ["| scene | N | solver | mean height after 15 frames (m) | after 30 (m) | "
           "end max / RMS strain | penetration at the end (mm) | Blender frames with an "
           "unconverged CG | accuracy figures identical over rounds |",
           "|---|---:|---|---:|---:|---:|---|---:|---|"]
    for (scene, n), runs in by_case(rows).items():
        for solver, rs in runs.items():
            r = rs[-1]
            out.append(
                f"| {scene} | {n} | {'Nucleus' if solver == 'ours' else 'Blender'} | "
                f"{r.get('mean_height_15', float('nan')):.4f} | "
                f"{r.get('mean_height_30', float('nan')):.4f} | "
                f"{pct(r['strain_max_end'])} / {pct(r['strain_rms_end'])} | "
                f"{penetration_cell(r, 'end_m')} | {r.get('cg_unconverged_frames', '–')} | {'yes' if identical(rs) else 'no'} |")
    return "\n".join(out)


def settings_table(settings):
    keys = sorted({k for s in settings.values() for k in s})
    out = ["| Blender setting | " + " | ".join(settings) + " |",
           "|---|" + "---:|" * len(settings)]
    for k in keys:
        cells = [fmt_setting(s.get(k, "")) for s in settings.values()]
        out.append(f"| `{k}` | " + " | ".join(cells) + " |")
    return "\n".join(out)


def fmt_setting(v):
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def session_setup(rows):
    """Rounds, threads and Blender's options of a session, from its rows."""
    ours = [r for r in rows if r["solver"] == "ours"] or rows
    theirs = [r for r in rows if r["solver"] == "blender"] or rows
    b = theirs[0].get("blender", {"tension": 400.0, "mass": 0.3, "quality": 5})
    return {"rounds": len({r["round"] for r in rows}), "threads": ours[0]["threads"],
            "blender_threads": theirs[0]["threads"], **b}


def document(rows, ctx, settings):
    """The whole of docs/blender.md."""
    a = argparse.Namespace(**session_setup(rows))
    return f"""# Nucleus against Blender's cloth solver

Generated by `bench/blender/blender.sh` on {ctx['date']}; do not edit by hand. How the scenes
are matched, what every figure means and what was found on the way:
[bench/blender/README.md](../bench/blender/README.md).

* Commit {ctx['commit']}{' (with uncommitted changes)' if ctx['dirty'] else ''}; Blender
  {ctx['blender']} (the `bpy` module from PyPI).
* Machine: {ctx['machine']}. Load average (1 min) during the session: {ctx['load_min']:.1f} to
  {ctx['load_max']:.1f}; the machine is shared with other builds, so times are compared as
  ratios within a round ({a.rounds} interleaved rounds, the order of the two solvers
  alternating), given as the median and (range) over the rounds.
* Command: `{ctx['command']}`. Each round runs, per scene,
  `RAYON_NUM_THREADS={a.threads} target/release/nucleus run scenes/SCENE.toml --out DIR -q`
  (at the scene's own settings) and
  `target/blender-venv/bin/python bench/blender/blender_run.py scenes/SCENE.toml --out DIR
  --threads {a.blender_threads} --tension {a.tension:g} --mass {a.mass:g} --quality {a.quality}`
  (the drapes at N = 128 add `--set 'objects.0.grid.resolution=[128,128]'` to both).
* Ours on {a.threads} thread(s); Blender on {a.blender_threads} (its task scheduler started
  with that many workers), at its default quality {a.quality} (steps a frame).

## Time and accuracy

ms / frame: mean wall time of one frame's step over the run (ours: `wall_s` of stats.csv;
Blender: `scene.frame_set`, reading the mesh back is not timed). CPU ms / frame: the process's
CPU time per frame (ours: the whole process, setup and output included, divided by the
frames), less sensitive to the load than the wall time. Strain: the extension
max(0, l/l0 - 1) of every mesh edge (rest lengths from frame 0), per frame its max and RMS;
*max strain* and *RMS strain* are their means over all frames, *peak* the largest per-frame max.
Penetration: the deepest any vertex got below the analytic sphere's or ground's surface over
the run. Intersecting pairs: triangles sharing no vertex that intersect in the last frame.
The two ratios are taken within each round (wall times, and CPU times, which the load disturbs
less) and given as median (range). *Equal or better accuracy?*: ours is no worse than Blender's on every one of max, RMS and peak
strain (0.01 % tolerance), penetration (0.1 mm) and intersecting pairs; it does not judge the
motion (a cloth held up stretches little): the next table does.

{table(rows)}

## Checks on the motion

The strain alone does not tell a cloth that falls as it should from one that is held back (an
unconverged solver stretches little). The mean height of the vertices after 15 and 30 frames
(0.25 and 0.5 s) shows whether both cloths fall alike; an unconverged CG in Blender (it stops
at 100 iterations) is what held its cloth up in the settings the README rejects. For the drape
the converged fall is known: our hard `stretch` at 320 substeps reaches −0.2416 / −0.4887 m at
N = 64 and −0.2421 / −0.4898 m at N = 128.

{motion_table(rows)}

## Blender's settings, per case

As written to each Blender run's run.json (everything else at Blender's defaults). Masses are
in Blender's unit (`mass` kg a vertex, see the README), times in its time unit.

{settings_table(settings)}
"""
