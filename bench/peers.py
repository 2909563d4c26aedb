#!/usr/bin/env python3
"""Nucleus side by side with the peer cloth solvers on the "drape" scene.

Run it through `bench/peers.sh` (which builds the release host and plugins, and creates the
peers' Python environment for `--live`); `bench/README.md` explains every option.

* Ours: `target/release/nucleus run scenes/drape.toml` at every N, over a sweep of substeps x
  iterations, for each scene variant (plain, with the `tether` kind, with `stretch_hierarchy`, by
  `stretch_newton`),
  on each thread count (RAYON_NUM_THREADS); the metrics are computed from the OBJ frames and stats.csv by `drape_metrics.py`, exactly as
  the peers' common.py does.
* Theirs: the peers' recorded sweeps (PEERS/raw/*.jsonl, `--recorded`, the default) and/or
  their scripts run live (`--live`), with the peers' own configurations (PEERS/sweep.py CONFIGS).
* Matched strain: for each solver, the least time per frame over its sweep at which strain_max
  <= 1 % (and <= 0.1 %); the same for strain_rms; and the ratio ours / theirs.

Prints markdown tables, appends every measured row to WORK/results.jsonl and writes the doc
(default docs/peers.md) with the date, machine, load and command, and beside it one SVG plot of
strain against time per N (`front_plot.py`). Python standard library only.
"""

import argparse
import datetime
import glob
import json
import os
import platform
import shlex
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import drape_metrics  # noqa: E402
import front_plot  # noqa: E402

THRESHOLDS = [("strain_max", 0.01), ("strain_max", 0.001), ("strain_rms", 0.01), ("strain_rms", 0.001)]
TETHER_BLOCK = '\n[[constraints]]\nkind = "tether"\nobjects = ["cloth"]\n'
# The drape's rest shape is flat, so the hierarchy's coarse edges may be straight lines.
HIERARCHY_BLOCK = ('\n[[constraints]]\nkind = "stretch_hierarchy"\nobjects = ["cloth"]\n'
                   'params = { straight_lengths = true }\n')
# Our variants of the scene: the constraint tables added to scenes/drape.toml.
VARIANTS = {
    "plain": "",
    "tether": TETHER_BLOCK,
    "hierarchy": HIERARCHY_BLOCK,
    "hierarchy+tether": HIERARCHY_BLOCK + TETHER_BLOCK,
    # The hierarchy once and the edges three times a substep (the `stretch` group's importance;
    # `--iterations` multiplies both): more fine passes per coarse one pay at RMS ~1 %.
    "hierarchy+edges3": HIERARCHY_BLOCK,
    # Every edge a stiff spring solved globally (the `stretch_newton` kind): its own scene,
    # below, and its own sweep (--newton-substeps x --newton-iterations, the Newton steps).
    "newton": "",
    # The same with the multigrid's sweeps under-relaxed (ω = 0.7) and 3 CG iterations a step.
    "newton_relaxed": "",
    # And a step the line search shortened followed by one more Newton step in the same pass.
    "newton_extra": "",
    # And the deep coarse operators kept through a substep (`refresh_depth = 2`).
    "newton_refresh": "",
    # And V(0,1) cycles with flexible CG (`pre_smoothing = false`).
    "newton_post": "",
}
# Variants that start from another scene than --scene (paths from the repository root).
VARIANT_SCENES = {
    "newton": os.path.join("scenes", "drape_newton.toml"),
    "newton_relaxed": os.path.join("scenes", "drape_newton.toml"),
    "newton_extra": os.path.join("scenes", "drape_newton.toml"),
    "newton_refresh": os.path.join("scenes", "drape_newton.toml"),
    "newton_post": os.path.join("scenes", "drape_newton.toml"),
}
# Scene settings a variant changes, as `nucleus run --set` arguments.
VARIANT_SETS = {
    "hierarchy+edges3": ["constraints.0.importance=3"],
    # Springs of compliance 1e-6 m/N (the scene's 1e-8 lock its multigrid's coarse space), 4 CG
    # iterations a Newton step, after 10 Gauss-Seidel passes a substep, the first coarse level
    # translating only (docs/decisions/newton-soft-springs.md).
    "newton": ["constraints.0.params.compliance=1e-6", "constraints.0.params.compression_compliance=1e-6",
               "constraints.0.params.cg_iterations=4", "constraints.0.params.start_passes=10",
               "constraints.0.params.plain_levels=1"],
    # The V-cycle's Gauss-Seidel sweeps under-relaxed (ω = 0.7) and 3 CG iterations a step
    # (docs/decisions/newton-relaxation.md).
    "newton_relaxed": ["constraints.0.params.compliance=1e-6", "constraints.0.params.compression_compliance=1e-6",
                       "constraints.0.params.cg_iterations=3", "constraints.0.params.start_passes=10",
                       "constraints.0.params.plain_levels=1", "constraints.0.params.relaxation=0.7"],
    # `newton_relaxed` with `extra_steps = 1`: a step the line search shortened is followed by
    # one more Newton step at once (docs/decisions/newton-extra-steps.md).
    "newton_extra": ["constraints.0.params.compliance=1e-6", "constraints.0.params.compression_compliance=1e-6",
                     "constraints.0.params.cg_iterations=3", "constraints.0.params.start_passes=10",
                     "constraints.0.params.plain_levels=1", "constraints.0.params.relaxation=0.7",
                     "constraints.0.params.extra_steps=1"],
    # `newton_extra` with `refresh_depth = 2`: at a substep's later Newton steps only the first
    # two coarse levels get new Galerkin operators (docs/decisions/newton-refresh-depth.md).
    "newton_refresh": ["constraints.0.params.compliance=1e-6", "constraints.0.params.compression_compliance=1e-6",
                       "constraints.0.params.cg_iterations=3", "constraints.0.params.start_passes=10",
                       "constraints.0.params.plain_levels=1", "constraints.0.params.relaxation=0.7",
                       "constraints.0.params.extra_steps=1", "constraints.0.params.refresh_depth=2"],
    # `newton_refresh` with `pre_smoothing = false`: each level of the V-cycle sweeps only after
    # its coarse correction (a V(0,1) cycle, CG's beta in the flexible form), reading each
    # level's matrix about once a cycle instead of twice (docs/decisions/newton-pre-smoothing.md).
    "newton_post": ["constraints.0.params.compliance=1e-6", "constraints.0.params.compression_compliance=1e-6",
                    "constraints.0.params.cg_iterations=3", "constraints.0.params.start_passes=10",
                    "constraints.0.params.plain_levels=1", "constraints.0.params.relaxation=0.7",
                    "constraints.0.params.extra_steps=1", "constraints.0.params.refresh_depth=2",
                    "constraints.0.params.pre_smoothing=false"],
}


def ints(s):
    return [int(x) for x in s.split(",") if x.strip()]


def parse_args():
    p = argparse.ArgumentParser(description="Nucleus vs the peer solvers on the drape scene")
    p.add_argument("--peers", default=os.path.join(ROOT, "..", "shared", "peers"),
                   help="the peers' directory (read only) [default: ../shared/peers from the repo root]")
    p.add_argument("--recorded", action="store_true",
                   help="use the peers' recorded sweeps PEERS/raw/*.jsonl (the default if --live is not given)")
    p.add_argument("--live", action="store_true", help="run the peers' scripts now (needs --venv)")
    p.add_argument("--live-configs", default="pypbd_pbd,pypbd_xpbd,mujoco_newton,newton_vbd,newton_xpbd",
                   help="peer configurations to run live (names from PEERS/sweep.py)")
    p.add_argument("--live-N", default=None, help="N values for the live peers [default: --N]")
    p.add_argument("--peer-substeps", default="1,2,5,10,20", help="live peer sweep: substeps")
    p.add_argument("--peer-iterations", default="1,2,5,10,20", help="live peer sweep: iterations")
    p.add_argument("--N", default="32,64,128", help="vertices per side, comma-separated")
    p.add_argument("--threads", default="1,2", help="our thread counts (RAYON_NUM_THREADS)")
    p.add_argument("--substeps", default="10,20,40,80,160,320", help="our sweep: substeps")
    p.add_argument("--iterations", default="1,2,4", help="our sweep: iterations")
    p.add_argument("--variants", default="plain,tether,hierarchy",
                   help="our scene variants, comma-separated: " + ", ".join(VARIANTS)
                        + " (constraint kinds added to scenes/drape.toml)")
    p.add_argument("--newton-substeps", default="1,2,3",
                   help="the `newton` variant's sweep: substeps (it replaces --substeps there)")
    p.add_argument("--newton-iterations", default="1,2,3,4",
                   help="the `newton` variant's sweep: Newton steps a substep (replaces --iterations)")
    p.add_argument("--no-ours", action="store_true", help="skip our runs (peers only)")
    p.add_argument("--limit-s", type=float, default=60.0,
                   help="skip a run whose predicted wall time exceeds this (s), predicted from the "
                        "previous run of the same solver and N scaled by substeps x iterations (as the peers' sweep.py)")
    p.add_argument("--frames", type=int, default=120)
    p.add_argument("--nucleus", default=os.path.join(ROOT, "target", "release", "nucleus"))
    p.add_argument("--scene", default=os.path.join(ROOT, "scenes", "drape.toml"))
    p.add_argument("--venv", default=os.path.join(ROOT, "target", "peers-venv"))
    p.add_argument("--work", default=os.path.join(ROOT, "target", "peers"),
                   help="scratch directory: run outputs (deleted after measuring), results.jsonl")
    p.add_argument("--tables-only", action="store_true",
                   help="run nothing: rebuild the tables from WORK/results.jsonl (rows of the last run)")
    p.add_argument("--doc", default=os.path.join(ROOT, "docs", "peers.md"), help="markdown file to write")
    p.add_argument("--no-doc", action="store_true", help="do not write the doc")
    p.add_argument("--command", default=None, help=argparse.SUPPRESS)  # the wrapper's command line
    a = p.parse_args()
    if not a.live:
        a.recorded = True
    return a


# ---------------------------------------------------------------------------------------------
# Ours


def our_scene(a, variant):
    if variant in VARIANT_SCENES:
        return os.path.join(ROOT, VARIANT_SCENES[variant])
    if not VARIANTS[variant]:
        return a.scene
    os.makedirs(a.work, exist_ok=True)
    path = os.path.join(a.work, f"drape_{variant.replace('+', '_')}.toml")
    with open(a.scene) as f:
        text = f.read()
    with open(path, "w") as f:
        f.write(text.rstrip("\n") + "\n" + VARIANTS[variant])
    return path


def our_name(variant):
    return "nucleus" + ("" if variant == "plain" else "+" + variant)


def run_ours(a, N, threads, variant, s, i):
    out = os.path.join(a.work, "runs", f"nucleus-N{N}-t{threads}-{variant}-{s}x{i}")
    shutil.rmtree(out, ignore_errors=True)
    cmd = [a.nucleus, "run", our_scene(a, variant), "--quiet", "--frames", str(a.frames),
           "--substeps", str(s), "--iterations", str(i), "--out", out,
           "--set", f"objects.0.grid.resolution=[{N},{N}]"]
    for setting_ in VARIANT_SETS.get(variant, []):
        cmd += ["--set", setting_]
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    t0 = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.time() - t0
    rec = {"solver": our_name(variant), "source": "live", "N": N,
           "substeps": s, "iters": i, "threads": threads, "wall_s": round(wall, 2)}
    if p.returncode != 0:
        rec["error"] = (p.stderr.strip().splitlines() or ["exit %d" % p.returncode])[-1][-400:]
    else:
        rec.update(drape_metrics.metrics(out, N, a.frames, 60))
    shutil.rmtree(out, ignore_errors=True)
    return rec


def sweep(runner, subs, iters, limit_s, frames, label):
    """Runs (s, i) combinations in order of work, skipping those predicted to exceed limit_s."""
    rows, ref = [], None
    for s, i in sorted(((s, i) for s in subs for i in iters), key=lambda c: (c[0] * c[1], c[0])):
        work = s * i
        if ref is not None:
            pred = ref[1] * frames * work / ref[0]
            if pred > limit_s:
                print(f"  {label} {s}x{i}: skipped (predicted {pred:.0f} s > {limit_s:.0f} s)", flush=True)
                continue
        rec = runner(s, i)
        if "time_per_frame_s" in rec:
            ref = (work, rec["time_per_frame_s"])
        rows.append(rec)
        print(f"  {label} {s}x{i}: {fmt_row(rec)}", flush=True)
    return rows


def fmt_row(r):
    if "error" in r:
        return "error: " + r["error"]
    flag = motion_flag(r)
    return (f"{r['time_per_frame_s'] * 1e3:.2f} ms/frame, strain max {fmt(r['strain_max'])}, "
            f"RMS {fmt(r['strain_rms'])}" + (" EXPLODED" if r.get("exploded") else "")
            + (f" ({flag})" if flag else ""))


motion_flag = front_plot.motion_flag


# ---------------------------------------------------------------------------------------------
# Theirs


def recorded_peers(peers):
    """The peers' recorded rows, one per (config, N, substeps, iters, threads); a clean re-run
    (`*_clean` in raw/extra.jsonl, measured with nothing else running) replaces the sweep's row."""
    best = {}
    for path in sorted(glob.glob(os.path.join(peers, "raw", "*.jsonl"))):
        for line in open(path):
            line = line.strip()
            if not line.startswith("{"):
                continue
            r = json.loads(line)
            if "config" not in r or "time_per_frame_s" not in r:
                continue  # probes without a configuration, skipped runs, errors
            clean = r["config"].endswith("_clean")
            config = r["config"][: -len("_clean")] if clean else r["config"]
            rec = dict(r, solver=config, source="recorded" + (" clean" if clean else ""),
                       file=os.path.basename(path))
            key = (config, r["N"], r["substeps"], r["iters"], r.get("threads", 1))
            if key not in best or clean:
                best[key] = rec
    return list(best.values())


def run_peer(a, config, N, s, i):
    sys.path.insert(0, a.peers)
    from sweep import CONFIGS  # the peers' own configuration table, read from their directory

    cmd0 = CONFIGS[config]
    py = os.path.join(a.venv, "bin", "python")
    cmd = [py, os.path.join(a.peers, cmd0[0])] + cmd0[1:] + [
        "--N", str(N), "--substeps", str(s), "--iters", str(i), "--frames", str(a.frames)]
    env = dict(os.environ, OMP_NUM_THREADS="1",
               WARP_CACHE_PATH=os.path.join(a.work, "warp-cache"))
    rec = {"solver": config, "source": "live", "N": N, "substeps": s, "iters": i, "threads": 1}
    t0 = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=a.limit_s * 2 + 60)
        lines = [l for l in p.stdout.splitlines() if l.startswith("{")]
        if lines:
            rec.update(json.loads(lines[-1]))
            rec["solver"], rec["source"] = config, "live"
        else:
            rec["error"] = (p.stderr or p.stdout).strip()[-400:]
    except subprocess.TimeoutExpired:
        rec["error"] = "timeout"
    rec["wall_s"] = round(time.time() - t0, 2)
    return rec


# ---------------------------------------------------------------------------------------------
# Tables


def fmt(x, nd=3):
    if x is None:
        return "-"
    if x != 0 and (abs(x) >= 1000 or abs(x) < 1e-3):
        return f"{x:.{nd}g}"
    return f"{x:.{nd}g}"


def ok(r):
    return "time_per_frame_s" in r and not r.get("exploded") and r.get("strain_max") is not None


def label(r):
    name = r["solver"]
    if r.get("source", "").startswith("live") and not name.startswith("nucleus"):
        name += " (live)"
    return name


def solvers(rows, N):
    """(label, threads) -> rows at N, ours first."""
    out = {}
    for r in rows:
        if r["N"] == N and ok(r):
            out.setdefault((label(r), r.get("threads", 1)), []).append(r)
    return dict(sorted(out.items(), key=lambda kv: (not kv[0][0].startswith("nucleus"), kv[0])))


def least_time(rows, metric, thr):
    """The fastest row within the bound, among those whose motion passes the checks if any
    does (`motion_flag`); else the fastest flagged one (its cell says what is wrong)."""
    hits = [r for r in rows if r[metric] is not None and r[metric] <= thr]
    right = [r for r in hits if not motion_flag(r)]
    return min(right or hits, key=lambda r: r["time_per_frame_s"]) if hits else None


def setting(r):
    return f"{r['substeps']}x{r['iters']}"


def cell(r):
    if not r:
        return "not reached"
    flag = motion_flag(r)
    return f"{r['time_per_frame_s'] * 1e3:.3g} ({setting(r)})" + (f" ({flag})" if flag else "")


def best_of(rows, metric):
    r = min(rows, key=lambda r: r[metric])
    return f"best {fmt(r[metric])}, {setting(r)}"


def matched_tables(rows, Ns, our_threads):
    out = []
    head = "| solver | threads | max <= 1 % | max <= 0.1 % | RMS <= 1 % | RMS <= 0.1 % |"
    for N in Ns:
        groups = solvers(rows, N)
        if not groups:
            continue
        out += [f"### N = {N}", "",
                "Least mean time per frame (ms) over each solver's sweep at which its strain (structural "
                "edges, last 60 frames) is at most the threshold, and the setting (substeps x iterations) "
                "that achieves it; *no*: no setting of the sweep gets there (its best strain and setting are given). "
                f"A run of ours whose cloth is *held up* (mean height after 0.5 s above {front_plot.MEAN_HEIGHT_30_M + front_plot.HELD_UP_M:.2f} m) "
                f"or that *makes energy* (a rise of more than {front_plot.ENERGY_RISE_J:g} J) is said so beside its time.",
                "", head, "|---|---:|---|---|---|---|"]
        for (name, th), rs in groups.items():
            cells = []
            for metric, thr in THRESHOLDS:
                r = least_time(rs, metric, thr)
                cells.append(cell(r) if r else f"no ({best_of(rs, metric)})")
            out.append(f"| {name} | {th} | " + " | ".join(cells) + " |")
        out.append("")
        # Ratios: ours (fastest of our variants) on each thread count against each peer (1 thread).
        ours = {th: [r for (n, t), rs in groups.items() if n.startswith("nucleus") and t == th for r in rs]
                for th in our_threads}
        peers = {k: rs for k, rs in groups.items() if not k[0].startswith("nucleus")}
        if not peers or not any(ours.values()):
            continue
        out += [f"Ratio of time per frame at matched strain, ours / theirs (N = {N}; ours: the fastest of "
                "our variants; < 1 means Nucleus is faster; *ours only*: the peer never "
                "reaches that strain in its sweep, *theirs only*: we do not, *neither*: no one does).", "",
                "| peer | threads | ours on | max <= 1 % | max <= 0.1 % | RMS <= 1 % | RMS <= 0.1 % |",
                "|---|---:|---:|---:|---:|---:|---:|"]
        for (name, th), prs in peers.items():
            for oth in our_threads:
                if not ours[oth]:
                    continue
                cells = []
                for metric, thr in THRESHOLDS:
                    o, t = least_time(ours[oth], metric, thr), least_time(prs, metric, thr)
                    if o and t:
                        cells.append(f"{o['time_per_frame_s'] / t['time_per_frame_s']:.3g}")
                    else:
                        cells.append("ours only" if o else ("theirs only" if t else "neither"))
                out.append(f"| {name} | {th} | {oth} | " + " | ".join(cells) + " |")
        out.append("")
    return out


def pareto_tables(rows, Ns):
    out = []
    for N in Ns:
        groups = solvers(rows, N)
        if not groups:
            continue
        out += [f"### N = {N}", "", "| solver | threads | substeps x iters | ms/frame | strain max | strain RMS | source | motion |",
                "|---|---:|---|---:|---:|---:|---|---|"]
        for (name, th), rs in groups.items():
            for r in front_plot.pareto(rs, "strain_max"):
                out.append(f"| {name} | {th} | {setting(r)} | {r['time_per_frame_s'] * 1e3:.3g} | "
                           f"{fmt(r['strain_max'])} | {fmt(r['strain_rms'])} | {r.get('source', '')} | "
                           f"{motion_flag(r)} |")
        out.append("")
    return out


def full_table(rows):
    out = ["| solver | N | threads | substeps x iters | ms/frame | strain max | strain RMS | max peak | min y "
           "| mean y at 0.5 s | energy rise (J) | motion | energy at the end (J) |",
           "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---|---:|"]
    for r in sorted(rows, key=lambda r: (r["N"], r["solver"], r.get("threads", 1), r["substeps"], r["iters"])):
        if "error" in r:
            out.append(f"| {label(r)} | {r['N']} | {r.get('threads', 1)} | {setting(r)} | error: {r['error'][:80]} | | | | | | | | |")
        elif "time_per_frame_s" in r:
            out.append(f"| {label(r)} | {r['N']} | {r.get('threads', 1)} | {setting(r)} | "
                       f"{r['time_per_frame_s'] * 1e3:.3g} | {fmt(r['strain_max'])} | {fmt(r['strain_rms'])} | "
                       f"{fmt(r.get('strain_max_peak'))} | {fmt(r.get('min_height'))} | "
                       f"{fmt(r.get('mean_height_30'))} | {fmt(r.get('energy_rise_j'))} | "
                       + ("exploded" if r.get("exploded") else motion_flag(r))
                       + f" | {fmt(r.get('energy_end_j'))} |")
    return out


# ---------------------------------------------------------------------------------------------


def sh(cmd):
    try:
        return subprocess.run(cmd, capture_output=True, text=True, shell=True).stdout.strip()
    except OSError:
        return ""


def machine():
    model = sh("lscpu | sed -n 's/^Model name: *//p' | head -1") or platform.processor()
    return {
        "model": model,
        "cores": sh("nproc"),
        "os": platform.platform(),
        "rustc": sh("rustc --version"),
        "commit": sh(f"git -C {shlex.quote(ROOT)} rev-parse --short HEAD"),
        "dirty": bool(sh(f"git -C {shlex.quote(ROOT)} status --porcelain --untracked-files=no")),
    }


def load():
    return sh("uptime").split("load average:")[-1].strip()


def main():
    a = parse_args()
    Ns, threads = ints(a.N), ints(a.threads)
    live_Ns = ints(a.live_N) if a.live_N else Ns
    os.makedirs(a.work, exist_ok=True)
    results = os.path.join(a.work, "results.jsonl")
    started = datetime.datetime.now().astimezone()
    loads = [load()]
    rows = []
    if a.tables_only:
        saved = [json.loads(l) for l in open(results) if l.strip()]
        last = max(r.get("run_id", "") for r in saved)
        rows = [r for r in saved if r.get("run_id") == last and "meta" not in r]
        meta = [r["meta"] for r in saved if r.get("run_id") == last and "meta" in r]
        if meta:
            started = datetime.datetime.fromisoformat(meta[-1]["started"])
            loads, a.command = meta[-1]["loads"], meta[-1]["command"]
            a.recorded, a.live = meta[-1]["recorded"], meta[-1]["live"]
    else:
        run_id = started.isoformat(timespec="seconds")

        def keep(rec):
            rec["run_id"] = run_id
            with open(results, "a") as f:
                f.write(json.dumps(rec) + "\n")
            rows.append(rec)

        if not a.no_ours:
            if not os.path.exists(a.nucleus):
                sys.exit(f"{a.nucleus} is missing: run bench/peers.sh (it builds it), or cargo xtask plugins --release")
            variants = [v.strip() for v in a.variants.split(",") if v.strip()]
            for v in variants:
                if v not in VARIANTS:
                    sys.exit(f"unknown variant {v!r}: choose from {', '.join(VARIANTS)}")
            for N in Ns:
                for th in threads:
                    for variant in variants:
                        name = f"{our_name(variant)} N={N} threads={th}"
                        print(name, flush=True)
                        subs, iters = ((a.newton_substeps, a.newton_iterations) if variant.startswith("newton")
                                       else (a.substeps, a.iterations))
                        for r in sweep(lambda s, i: run_ours(a, N, th, variant, s, i),
                                       ints(subs), ints(iters), a.limit_s, a.frames, name):
                            keep(r)
                loads.append(load())
        if a.live:
            for config in a.live_configs.split(","):
                for N in live_Ns:
                    name = f"{config} (live) N={N}"
                    print(name, flush=True)
                    for r in sweep(lambda s, i: run_peer(a, config, N, s, i), ints(a.peer_substeps),
                                   ints(a.peer_iterations), a.limit_s, a.frames, name):
                        keep(r)
                    loads.append(load())
        loads.append(load())
        a.command = a.command or " ".join(shlex.quote(x) for x in sys.argv)
        with open(results, "a") as f:
            f.write(json.dumps({"run_id": run_id, "meta": {
                "started": run_id, "loads": loads, "command": a.command,
                "recorded": a.recorded, "live": a.live}}) + "\n")
    if a.recorded:
        rows += [r for r in recorded_peers(a.peers) if r["N"] in Ns]

    matched = matched_tables(rows, Ns, threads)
    print("\n".join(matched))
    if a.no_doc:
        return 0
    m = machine()
    command = a.command
    # One plot per N beside the doc (front_plot.py): strain against time, every solver.
    plots = []
    for N in Ns:
        svg = front_plot.plot(rows, N)
        if svg:
            path = os.path.splitext(os.path.abspath(a.doc))[0] + f"_N{N}.svg"
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w") as f:
                f.write(svg)
            plots.append((N, os.path.basename(path)))
    doc = [
        "# Nucleus against the peer cloth solvers: the drape scene",
        "",
        f"Generated by `bench/peers.sh` on {started.strftime('%Y-%m-%d %H:%M %Z')}; do not edit by hand. "
        "How to run it and what every column means: [bench/README.md](../bench/README.md).",
        "",
        f"* Machine: {m['model']}, {m['cores']} cores; {m['os']}; {m['rustc']}; commit {m['commit']}"
        + (" (with uncommitted changes)" if m["dirty"] else "") + ".",
        f"* Load average (1, 5, 15 min) during the run: {'; '.join(loads)}. The machine is shared with other "
        "builds: treat differences below about 30 % as noise.",
        f"* Command: `{command}`",
        "* Scene: `scenes/drape.toml` (the peers' drape: 1 m cloth, N x N, two corners pinned, 120 frames at "
        "60 fps, no damping), hard stretch on every mesh edge (`nucleus`), plus the `tether` kind "
        "(`nucleus+tether`) or the `stretch_hierarchy` kind with straight lengths (`nucleus+hierarchy`; "
        "`nucleus+hierarchy+edges3`: with the edges' importance 3); `nucleus+newton`: `scenes/drape_newton.toml`, "
        "every edge a stiff spring (compliance 1e-6 m/N) solved by Newton steps (the iterations), each by 4 "
        "multigrid-preconditioned CG iterations (the first coarse level translating only, `plain_levels = 1`), "
        "after 10 Gauss-Seidel passes a substep (`nucleus+newton_relaxed`: 3 CG iterations, the V-cycle's "
        "sweeps under-relaxed, `relaxation = 0.7`; `nucleus+newton_extra`: that and `extra_steps = 1`, one more "
        "Newton step after a step the line search shortened; `nucleus+newton_refresh`: that and `refresh_depth = 2`, "
        "the deep coarse operators kept through a substep; `nucleus+newton_post`: that and `pre_smoothing = false`, "
        "V(0,1) cycles with flexible CG); "
        "no bending. Peers: "
        + ("their recorded sweeps (`PEERS/raw/*.jsonl`, 1 thread unless noted; `recorded clean` rows were "
           "re-run with nothing else running)" if a.recorded else "")
        + (" and " if a.recorded and a.live else "")
        + ("their scripts run live now, 1 thread (`(live)`)" if a.live else "")
        + ". Their models differ (PBD, XPBD, soft constraints, VBD): see the caveats in the peers' README.",
        "* Metrics, identical for every solver: time = mean step wall time per frame of frames 2..120; "
        "strain = |l - l0| / l0 over the 2N(N-1) structural edges, per frame max and RMS, averaged over "
        "the last 60 frames (RMS describes the cloth as a whole; the max sits at the pinned corners, a "
        "point-load singularity, while the solution is loose, and in the folds of the swinging cloth once "
        "it is tight: see bench/README.md).",
        "",
        "## Matched strain",
        "",
    ] + matched + ([
        "## Plots",
        "",
        "RMS and max strain against time per frame, every run (dots) and each solver's Pareto front "
        "(lines), the target of the benchmark issue shaded (`bench/front_plot.py`).",
        "",
    ] + [f"![N = {N}]({name})" for N, name in plots] + [""] if plots else []) + [
        "## Pareto fronts (settings not beaten by a faster one on max strain)",
        "",
    ] + pareto_tables(rows, Ns) + [
        "## Every run of ours",
        "",
    ] + full_table([r for r in rows if r["solver"].startswith("nucleus")]) + [""]
    live_peers = [r for r in rows if not r["solver"].startswith("nucleus") and r.get("source") == "live"]
    if live_peers:
        doc += ["## Every live run of the peers", ""] + full_table(live_peers) + [""]
    os.makedirs(os.path.dirname(os.path.abspath(a.doc)), exist_ok=True)
    with open(a.doc, "w") as f:
        f.write("\n".join(doc))
    print(f"wrote {a.doc}; rows in {results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
