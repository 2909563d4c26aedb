#!/usr/bin/env python3
"""Nucleus against Blender's cloth solver, run time against error, in one interleaved session.

Run it through bench/blender/blender.sh (builds ours, makes the bpy environment); every option
is in --help and bench/blender/README.md. For each round and each scene it runs ours
(`target/release/nucleus run SCENE --out DIR`, RAYON_NUM_THREADS = --threads) and Blender
(bench/blender/blender_run.py on one thread), alternating which goes first, computes the same
metrics from both outputs with bench/cloth_metrics.py, appends a JSON row per run to --jsonl
and writes the table to --doc. Times are compared as ratios within a round (ours / Blender),
then summarised over the rounds (median and range), because the machine is shared.
"""

import argparse
import datetime
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
import cloth_metrics  # noqa: E402
import report  # noqa: E402
from scene_spec import load_spec  # noqa: E402

NUCLEUS = os.path.join(ROOT, "target", "release", "nucleus")
SCENES = ["drape", "drape_newton", "cloth_on_sphere", "cloth_heap"]


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenes", default=",".join(SCENES), help="scene names under scenes/")
    p.add_argument("--N", default="64",
                   help="the drapes' resolutions, e.g. 64,128 (the other scenes stay at 64)")
    p.add_argument("--rounds", type=int, default=3, help="interleaved rounds (default 3)")
    p.add_argument("--threads", type=int, default=1, help="our RAYON_NUM_THREADS (default 1)")
    p.add_argument("--blender-threads", type=int, default=1)
    p.add_argument("--frames", type=int, help="override every scene's frame count")
    p.add_argument("--tension", type=float, default=400.0, help="Blender's hard-edge stiffness")
    p.add_argument("--mass", type=float, default=0.3, help="Blender's mass a vertex (kg)")
    p.add_argument("--quality", type=int, default=5, help="Blender's steps a frame")
    p.add_argument("--work", default=os.path.join(ROOT, "target", "blender"))
    p.add_argument("--jsonl", help="raw rows [default WORK/results.jsonl]")
    p.add_argument("--doc", default=os.path.join(ROOT, "docs", "blender.md"))
    p.add_argument("--no-doc", action="store_true", help="print the table only")
    p.add_argument("--tables-only", action="store_true",
                   help="rebuild the doc from the last session's rows in --jsonl, run nothing")
    p.add_argument("--command", default=None, help=argparse.SUPPRESS)
    return p.parse_args(argv)


def cases(a):
    """(scene, N, our --set overrides) of every case."""
    out = []
    for scene in a.scenes.split(","):
        for n in (a.N.split(",") if scene.startswith("drape") else ["64"]):
            sets = [] if n == "64" else [f"objects.0.grid.resolution=[{n},{n}]"]
            out.append((scene, int(n), sets))
    return out


def timed(cmd, env=None):
    """Run cmd; (its wall time, the CPU time of the child, stdout). Fails loudly."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, p.stdout


def ours_command(a, scene, sets, out, extra=()):
    cmd = [NUCLEUS, "run", os.path.join(ROOT, "scenes", f"{scene}.toml"), "--out", out, "-q",
           *extra]
    for s in sets:
        cmd += ["--set", s]
    if a.frames:
        cmd += ["--frames", str(a.frames)]
    return cmd


def blender_command(a, scene, sets, out):
    cmd = [sys.executable, os.path.join(HERE, "blender_run.py"),
           os.path.join(ROOT, "scenes", f"{scene}.toml"), "--out", out,
           "--threads", str(a.blender_threads), "--tension", str(a.tension),
           "--mass", str(a.mass), "--quality", str(a.quality)]
    for s in sets:
        cmd += ["--set", s]
    if a.frames:
        cmd += ["--frames", str(a.frames)]
    return cmd


def run_one(a, solver, scene, n, sets, rnd, extra=()):
    """Run one solver on one case (`extra`: more arguments for ours); its metrics row."""
    out = os.path.join(a.work, f"{scene}_N{n}", solver)
    shutil.rmtree(out, ignore_errors=True)
    load0 = os.getloadavg()[0]
    if solver == "ours":
        env = dict(os.environ, RAYON_NUM_THREADS=str(a.threads))
        wall, cpu, _ = timed(ours_command(a, scene, sets, out, extra), env)
    else:
        wall, cpu, _ = timed(blender_command(a, scene, sets, out))
    spec = load_spec(os.path.join(ROOT, "scenes", f"{scene}.toml"), sets)
    row = {"solver": solver, "scene": scene, "N": n, "round": rnd,
           "threads": a.threads if solver == "ours" else a.blender_threads,
           "blender": {"tension": a.tension, "mass": a.mass, "quality": a.quality},
           "process_wall_s": wall, "process_cpu_s": cpu,
           "load_before": load0, "load_after": os.getloadavg()[0]}
    row.update(cloth_metrics.run_metrics(out, spec.triangles, colliders_of(spec)))
    if solver == "blender":
        row["cpu_per_frame_s"] = float(cloth_metrics.wall_times(out, "cpu_s").mean())
        row["cg_unconverged_frames"] = int(
            (cloth_metrics.wall_times(out, "cg_converged") == 0).sum())
    else:
        row["cpu_per_frame_s"] = cpu / row["frames"]   # includes setup and output
    return row


def colliders_of(spec):
    """The analytic colliders of a spec, named for the metrics."""
    out = {}
    for c in spec.colliders:
        name = "ground" if c.kind == "plane" else c.kind
        out[name] = (c.kind, c.center, c.radius if c.kind == "sphere" else c.normal)
    return out


def session(a):
    """Every round, every case, both solvers alternately first; the rows."""
    rows = []
    for rnd in range(a.rounds):
        for k, (scene, n, sets) in enumerate(cases(a)):
            order = ["ours", "blender"] if (rnd + k) % 2 == 0 else ["blender", "ours"]
            for solver in order:
                row = run_one(a, solver, scene, n, sets, rnd)
                rows.append(row)
                print(f"round {rnd} {scene} N={n} {solver}: "
                      f"{1000 * row['time_per_frame_s']:.0f} ms/frame, strain max "
                      f"{100 * row['strain_max']:.2f} % rms {100 * row['strain_rms']:.3f} %, "
                      f"pairs {row['intersecting_pairs_end']} (load {row['load_before']:.1f})",
                      file=sys.stderr, flush=True)
    return rows


def git(*args):
    p = subprocess.run(["git", *args], capture_output=True, text=True, cwd=ROOT)
    return p.stdout.strip()


def context(a, rows):
    """Date, commit, command, machine and load of the session, for the doc and the rows."""
    loads = [r["load_before"] for r in rows] + [r["load_after"] for r in rows]
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                if line.startswith("model name")), platform.processor())
    return {"date": rows[0].get("date", datetime.datetime.now().strftime("%Y-%m-%d %H:%M")),
            "commit": rows[0].get("commit", git("rev-parse", "--short", "HEAD")),
            "dirty": rows[0].get("dirty", bool(git("status", "--porcelain", "--", "bench",
                                                   "scenes", "core", "plugins", "host"))),
            "command": rows[0].get("command", a.command or " ".join(sys.argv)),
            "machine": f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}",
            "load_min": min(loads), "load_max": max(loads), "blender": blender_version(a, rows)}


def blender_version(a, rows):
    for scene, n in {(r["scene"], r["N"]) for r in rows}:
        path = os.path.join(a.work, f"{scene}_N{n}", "blender", "run.json")
        if os.path.exists(path):
            with open(path) as f:
                return json.load(f)["blender"]
    return "?"


def last_session(path):
    """The rows of the last session appended to the JSONL file at `path`."""
    with open(path) as f:
        rows = [json.loads(line) for line in f if line.strip()]
    return [r for r in rows if (r["date"], r["commit"]) == (rows[-1]["date"], rows[-1]["commit"])]


def main(argv=None):
    a = parse_args(argv)
    a.jsonl = a.jsonl or os.path.join(a.work, "results.jsonl")
    os.makedirs(a.work, exist_ok=True)
    if a.tables_only:
        rows = last_session(a.jsonl)
        ctx = context(a, rows)
    else:
        cloth_metrics.self_test()
        rows = session(a)
        ctx = context(a, rows)
        with open(a.jsonl, "a") as f:
            for r in rows:
                keep = {k: ctx[k] for k in ("date", "commit", "dirty", "command")}
                f.write(json.dumps(dict(r, **keep)) + "\n")
    settings = blender_settings(a, rows)
    text = report.document(rows, ctx, settings)
    print(report.table(rows))
    if not a.no_doc:
        with open(a.doc, "w") as f:
            f.write(text)
        done = "" if a.tables_only else f" and appended {len(rows)} rows to {a.jsonl}"
        print(f"wrote {a.doc}{done}", file=sys.stderr)


def blender_settings(a, rows):
    """{case: Blender's settings} from the last runs' run.json."""
    out = {}
    for scene, n in report.by_case(rows):
        path = os.path.join(a.work, f"{scene}_N{n}", "blender", "run.json")
        with open(path) as f:
            out[f"{scene} N={n}"] = json.load(f)["settings"]
    return out


if __name__ == "__main__":
    main()
