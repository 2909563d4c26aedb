#!/usr/bin/env python3
"""Writes docs/performance.md from the results files the benchmarks wrote.

usage: python3 bench/perf_page.py [--root DIR] [--check]

Reads, relative to the repository root:
  docs/peers.md, docs/peers_2threads.md, docs/peers_newton.md   bench/peers.sh's sweeps
  docs/bench/<name>.csv with docs/bench/<name>.json              nucleus bench runs and
                                                                 bench/scenes.py's timings
  docs/stress.md                                                 the stress suite's table
and writes docs/performance.md (with --check: exits 1 if the page on disk differs).
Every figure on the page comes from those files; each section names its source, its date and
its commit. Python 3 standard library only.
"""

import argparse
import csv
import json
import os
import re
import sys

PEER_DOCS = [
    ("docs/peers.md", "Gauss-Seidel variants, 1 thread"),
    ("docs/peers_2threads.md", "Gauss-Seidel variants and `newton`, 2 threads"),
    ("docs/peers_newton.md", "The `stretch_newton` variants, 1 and 2 threads"),
]
BOUNDS = ["RMS <= 1 %", "RMS <= 0.1 %", "max <= 1 %", "max <= 0.1 %"]


def read(root, path):
    with open(os.path.join(root, path), encoding="utf-8") as f:
        return f.read()


def pct(fraction):
    """A strain given as a fraction, as a percentage with three significant digits."""
    return f"{float(fraction) * 100:.3g} %"


def setting(s):
    return s.replace("x", " × ")


def peers_header(text):
    """Date, commit, command and machine of a peers doc (bench/peers.py's header lines)."""
    date = re.search(r"on (\d{4}-\d\d-\d\d)", text)
    commit = re.search(r"commit ([0-9a-f]{7,})", text)
    command = re.search(r"\* Command: `([^`]*)`", text)
    machine = re.search(r"\* Machine: ([^;]*)", text)
    return {
        "date": date.group(1) if date else "?",
        "commit": commit.group(1) if commit else "?",
        "command": command.group(1) if command else "?",
        "machine": machine.group(1) if machine else "?",
    }


def parse_cell(cell):
    """'3.14 (80x2)' -> (3.14, '80x2', None); 'no (best 0.0068, 80x4)' -> (None, '80x4', 0.0068)."""
    m = re.match(r"([\d.e+-]+) \(([^)]*)\)", cell)
    if m:
        return float(m.group(1)), m.group(2), None
    m = re.match(r"no \(best ([\d.e+-]+), ([^)]*)\)", cell)
    if m:
        return None, m.group(2), float(m.group(1))
    return None, None, None


def matched_strain(text):
    """{N: [(solver, threads, {bound: cell})]} from a peers doc's "Matched strain" tables."""
    out = {}
    section = text.split("## Matched strain", 1)[-1].split("\n## ", 1)[0]
    for block in section.split("### N = ")[1:]:
        n = int(block.split("\n", 1)[0])
        rows = []
        header = None
        for line in block.splitlines():
            if line.startswith("| solver |"):
                header = [c.strip() for c in line.strip("|").split("|")]
                continue
            if header is None or not line.startswith("|") or line.startswith("|---"):
                if header is not None and rows and not line.startswith("|"):
                    break
                continue
            cells = [c.strip() for c in line.strip("|").split("|")]
            row = dict(zip(header, cells))
            rows.append((row["solver"], row["threads"], row))
        out[n] = rows
    return out


def best(rows, bound, ours, threads=None):
    """The fastest row reaching `bound` among ours (or the peers'), else the best strain."""
    reached, missed = None, None
    for solver, t, row in rows:
        if solver.startswith("nucleus") != ours or (threads and t != threads):
            continue
        ms, s, strain = parse_cell(row.get(bound, ""))
        if ms is not None and (reached is None or ms < reached[0]):
            reached = (ms, solver, s, t)
        if strain is not None and (missed is None or strain < missed[0]):
            missed = (strain, solver, s, t)
    return reached, missed


def variant(solver):
    name = solver.split("+", 1)[1] if "+" in solver else "plain"
    return f"`{name}`"


def describe(reached, missed, ours):
    if reached:
        ms, solver, s, t = reached
        who = variant(solver) if ours else solver
        return f"**{ms:g} ms** ({who}, {setting(s)})"
    if missed:
        strain, solver, s, t = missed
        who = variant(solver) if ours else solver
        return f"not reached (best {pct(strain)}, {who} {setting(s)})"
    return "—"


def glance_section(root):
    """The fastest of ours (any sweep, any thread count) and of the peers at each bound."""
    lines = [
        "## At a glance",
        "",
        "The least time per frame at which any of our sweeps below, on any thread count, holds the "
        "drape's strain within each bound, against the best peer's recorded sweep (details, "
        "settings and sources in the next section). Whether the benchmark target — both bounds at "
        "N = 128 within 16 ms a frame on 2 cores — is met: "
        "[decisions/n128-target.md](decisions/n128-target.md).",
        "",
        "| N | bound | Nucleus | best peer |",
        "|---:|---|---|---|",
    ]
    tables = [matched_strain(read(root, path)) for path, _ in PEER_DOCS]
    for n in (64, 128):
        rows = [r for t in tables for r in t.get(n, [])]
        for bound in BOUNDS[:3]:
            ours = best(rows, bound, True)
            if ours[0]:
                ms, solver, s, t = ours[0]
                who = f"**{ms:g} ms** ({variant(solver)}, {setting(s)}, {t} thread{'s' if t != '1' else ''})"
            else:
                who = describe(*ours, True)
            theirs = describe(*best(rows, bound, False), False)
            lines.append(f"| {n} | {bound.replace('<=', '≤')} | {who} | {theirs} |")
    return lines


def peers_section(root):
    lines = ["## Against the peers: the drape", ""]
    lines.append(
        "The peers' own scene (`scenes/drape.toml`: a 1 m cloth of N × N vertices pinned at two "
        "corners, 120 frames at 60 fps, hard stretch on every edge) and their metrics: time is the "
        "mean step time per frame, strain is `|l − l0| / l0` over the structural edges averaged "
        "over the last 60 frames. Each cell is the least time per frame at which a solver's sweep "
        "holds the strain within the bound (its setting: substeps × iterations); the peers' "
        "figures are their recorded sweeps, on the machine they were recorded on. Method: "
        "[bench/README.md](../bench/README.md#benchpeerssh--the-drape-ours-and-theirs)."
    )
    for path, what in PEER_DOCS:
        text = read(root, path)
        h = peers_header(text)
        name = os.path.basename(path)
        lines += [
            "",
            f"### {what}",
            "",
            f"Source: [{name}]({name}) (every run, the Pareto fronts and plots), "
            f"{h['date']}, commit {h['commit']}, {h['machine']}; `{h['command']}`.",
        ]
        table = matched_strain(text)
        threads = sorted({t for rows in table.values() for s, t, _ in rows if s.startswith("nucleus")})
        for n in sorted(table):
            rows = table[n]
            lines += ["", f"N = {n}:", ""]
            cols = [f"Nucleus, {t} thread{'s' if t != '1' else ''}" for t in threads]
            lines.append("| bound | " + " | ".join(cols) + " | best peer |")
            lines.append("|---|" + "---|" * (len(cols) + 1))
            for bound in BOUNDS:
                ours = [describe(*best(rows, bound, True, t), True) for t in threads]
                theirs = describe(*best(rows, bound, False), False)
                shown = bound.replace("<=", "≤")
                lines.append(f"| {shown} | " + " | ".join(ours) + f" | {theirs} |")
    return lines


def bench_source(root, name):
    """The rows of docs/bench/<name>.csv and its provenance (docs/bench/<name>.json)."""
    with open(os.path.join(root, "docs", "bench", name + ".csv"), encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    with open(os.path.join(root, "docs", "bench", name + ".json"), encoding="utf-8") as f:
        meta = json.load(f)
    return rows, meta


def provenance(name, meta):
    return (
        f"Source: [bench/{name}.csv](bench/{name}.csv), {meta['date']}, commit {meta['commit']}, "
        f"{meta['machine']}, {meta['threads']}; `{meta['command']}`."
    )


def small_steps_section(root):
    rows, meta = bench_source(root, "drape32_small_steps")
    by = {(int(r["substeps"]), int(r["iterations"])): r for r in rows}
    lines = [
        "## Small steps beat iterations",
        "",
        "At equal work, `n` substeps of one pass hold far less strain and position error than one "
        "substep of `n` passes (Macklin et al. 2019). The 32 × 32 drape, 60 frames, error against a "
        "converged reference run. " + provenance("drape32_small_steps", meta),
        "",
        "| passes per frame | substeps × iterations | ms/frame | RMS strain (mean over frames) "
        "| RMS position error (mean, m) |",
        "|---:|---|---:|---:|---:|",
    ]
    for n in sorted({s for s, i in by if i == 1 and (1, s) in by and s > 1}):
        for key in [(n, 1), (1, n)]:
            r = by[key]
            lines.append(
                f"| {n} | {key[0]} × {key[1]} | {float(r['wall_s_per_frame']) * 1e3:.3g} | "
                f"{pct(r['stretch.rms_mean'])} | {float(r['pos_rms_mean']):.3g} |"
            )
    return lines


def front_section(root):
    rows, meta = bench_source(root, "drape64_front")
    pts = sorted(
        (float(r["wall_s_per_frame"]) * 1e3, float(r["stretch.rms_mean"]), r) for r in rows
        if not r.get("failure")
    )
    front, least = [], float("inf")
    for ms, rms, r in pts:
        if rms < least:
            front.append((ms, rms, r))
            least = rms
    lines = [
        "## The 64 × 64 drape's front",
        "",
        "The settings no faster setting beats on RMS strain. " + provenance("drape64_front", meta),
        "",
        "| substeps × iterations | ms/frame | RMS strain (mean over frames) | max strain (mean) "
        "| RMS position error at the end (m) |",
        "|---|---:|---:|---:|---:|",
    ]
    for ms, rms, r in front:
        lines.append(
            f"| {r['substeps']} × {r['iterations']} | {ms:.3g} | {pct(rms)} | "
            f"{pct(r['stretch.max_mean'])} | {float(r['pos_rms_end']):.3g} |"
        )
    return lines


def scenes_section(root):
    if not os.path.exists(os.path.join(root, "docs", "bench", "scenes.csv")):
        return ["## Shipped scenes", "", "No results yet: run `python3 bench/scenes.py`."]
    rows, meta = bench_source(root, "scenes")
    threads = sorted({int(r["threads"]) for r in rows})
    names = []
    for r in rows:
        if r["scene"] not in names:
            names.append(r["scene"])
    lines = [
        "## Shipped scenes",
        "",
        "Mean step time per frame (frames 2 to the last, output excluded) of each scene as shipped "
        "(`--set` arguments as listed), the same frames on every thread count. "
        + provenance("scenes", meta),
        "",
        "| scene | frames | " + " | ".join(f"ms/frame, {t} thread{'s' if t > 1 else ''}" for t in threads) + " |",
        "|---|---:|" + "---:|" * len(threads),
    ]
    for name in names:
        mine = {int(r["threads"]): r for r in rows if r["scene"] == name}
        first = next(iter(mine.values()))
        cells = [f"{float(mine[t]['ms_per_frame']):.3g}" if t in mine else "—" for t in threads]
        lines.append(f"| {name} | {first['frames']} | " + " | ".join(cells) + " |")
    return lines


def stress_section(root):
    text = read(root, "docs/stress.md")
    rows = [l for l in text.splitlines() if l.startswith("| ") and not l.startswith("| case |")]
    passed = sum(1 for l in rows if "| yes |" in l)
    failed = [l.split("|")[1].strip() for l in rows if "| NO |" in l]
    lines = [
        "## Numerical stability",
        "",
        f"The stress suite (`tests/tests/stress.rs`: extreme stiffness, mass ratios, step sizes, "
        f"speeds and degenerate geometry, checked for finiteness, energy growth, speed and "
        f"tunnelling after every substep): **{passed} of the {len(rows)} cases in its table pass**; the "
        f"{len(failed)} that fail are known and documented. Source: [stress.md](stress.md).",
    ]
    return lines


def page(root):
    out = [
        "# Performance",
        "",
        "Generated by `python3 bench/perf_page.py` from the results files the benchmarks write; do "
        "not edit by hand. To refresh a section, re-run its benchmark (the command is in its "
        "source line; [bench/README.md](../bench/README.md) lists them all), then this script. "
        "Every figure was measured on a shared 2-core VM: compare rows of one table, not figures "
        "across tables, machines or dates. Why each default and option is what it is, with the "
        "measurements behind it: [decisions](decisions/README.md).",
        "",
    ]
    for section in [glance_section, peers_section, small_steps_section, front_section, scenes_section, stress_section]:
        out += section(root) + [""]
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--root", default=os.path.dirname(here), help="the repository root")
    ap.add_argument("--check", action="store_true", help="exit 1 if docs/performance.md is stale")
    args = ap.parse_args()
    text = page(args.root)
    target = os.path.join(args.root, "docs", "performance.md")
    if args.check:
        with open(target, encoding="utf-8") as f:
            if f.read() != text:
                print("docs/performance.md is stale: run python3 bench/perf_page.py", file=sys.stderr)
                sys.exit(1)
        return
    with open(target, "w", encoding="utf-8") as f:
        f.write(text)
    print(f"wrote {target}", file=sys.stderr)


if __name__ == "__main__":
    main()
