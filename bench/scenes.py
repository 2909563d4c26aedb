#!/usr/bin/env python3
"""Times shipped scenes and writes docs/bench/scenes.csv (+ scenes.json, its provenance), the
source of the "Shipped scenes" table of docs/performance.md (bench/perf_page.py).

usage: python3 bench/scenes.py [--frames N] [--threads 1,2] [--out docs/bench/scenes.csv]
                               [SCENE[:KEY=VALUE[;KEY=VALUE...]] ...]

Needs the release build (`cargo xtask plugins --release`). Each scene runs once per thread count
with `nucleus run --frames N --threads T`; the time is the mean `wall_s` (the step alone, output
excluded) of frames 2..N in its stats.csv. Without scenes, the default list below. A scene may
carry `--set` overrides after a colon, separated by `;`:
`scenes/drape.toml:objects.0.grid.resolution=[128,128]`.
Python 3 standard library only.
"""

import argparse
import csv
import datetime
import json
import os
import platform
import shutil
import subprocess
import sys

DEFAULT = [
    "scenes/hanging_cloth.toml",
    "scenes/drape.toml:objects.0.grid.resolution=[128,128]",
    "scenes/soccer_net.toml",
    "scenes/cloth_on_sphere.toml",
    "scenes/cloth_heap.toml",
]


def git(root, *args):
    try:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"


def cpu_name():
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "?"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=DEFAULT)
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--out", default="docs/bench/scenes.csv")
    args = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    host = os.path.join(root, "target", "release", "nucleus")
    if not os.path.exists(host):
        sys.exit(f"{host} is missing: run `cargo xtask plugins --release` first")
    work = os.path.join(root, "target", "bench-scenes")
    load_before = os.getloadavg()[0]
    rows = []
    for spec in args.scenes:
        path, _, sets = spec.partition(":")
        name = os.path.splitext(os.path.basename(path))[0]
        overrides = [s for s in sets.split(";") if s] if sets else []
        for t in [int(x) for x in args.threads.split(",")]:
            out = os.path.join(work, f"{name}-{t}")
            shutil.rmtree(out, ignore_errors=True)
            cmd = [host, "run", os.path.join(root, path), "--quiet", "--frames", str(args.frames),
                   "--threads", str(t), "--out", out]
            for s in overrides:
                cmd += ["--set", s]
            subprocess.run(cmd, check=True)
            with open(os.path.join(out, "stats.csv"), encoding="utf-8") as f:
                walls = [float(r["wall_s"]) for r in csv.DictReader(f) if int(r["frame"]) >= 2]
            ms = 1e3 * sum(walls) / len(walls)
            shown = name + "".join(f" `{s}`" for s in overrides)
            rows.append({"scene": shown, "frames": args.frames, "threads": t, "ms_per_frame": f"{ms:.4g}"})
            print(f"{shown}: {t} thread(s), {ms:.4g} ms a frame", file=sys.stderr)
            shutil.rmtree(out, ignore_errors=True)
    target = os.path.join(root, args.out)
    with open(target, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=["scene", "frames", "threads", "ms_per_frame"])
        w.writeheader()
        w.writerows(rows)
    dirty = " (with uncommitted changes)" if git(root, "status", "--porcelain", "--untracked-files=no") else ""
    meta = {
        "date": datetime.date.today().isoformat(),
        "commit": git(root, "rev-parse", "--short", "HEAD") + dirty,
        "machine": f"{cpu_name()}, {os.cpu_count()} cores, load average {load_before:.1f} before the runs "
        f"and {os.getloadavg()[0]:.1f} after (other work on the machine slows every figure)",
        "threads": "threads as listed",
        "command": "python3 bench/scenes.py " + " ".join(sys.argv[1:]),
    }
    with open(os.path.splitext(target)[0] + ".json", "w", encoding="utf-8") as f:
        json.dump(meta, f, indent=1)
        f.write("\n")
    print(f"wrote {target}", file=sys.stderr)


if __name__ == "__main__":
    main()
