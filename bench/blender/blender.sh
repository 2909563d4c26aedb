#!/usr/bin/env bash
# Nucleus against Blender's cloth solver on our own scenes: builds the release host and
# plugins, creates Blender's Python environment (bpy + numpy from PyPI, python3.11, about
# 400 MB) under target/blender-venv when it is missing, and runs bench/blender/compare.py
# (every option: bench/blender/README.md and --help).
#
#   bench/blender/blender.sh                        # drape, drape_newton, cloth_on_sphere, cloth_heap; 3 rounds
#   bench/blender/blender.sh --N 64,128             # the drapes at N = 128 as well
#   bench/blender/blender.sh --threads 2            # ours on 2 threads (Blender stays on 1)
#   bench/blender/blender.sh --calibrate            # the tension scan (calibrate.py) instead
#
# Writes docs/blender.md and appends raw rows to target/blender/results.jsonl. Nothing here
# is part of the test suite.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"

venv="$root/target/blender-venv"
python_for_venv="${PYTHON:-python3.11}"

if [[ ! -x "$venv/bin/python" ]]; then
    echo "creating Blender's Python environment in $venv (pip: bpy, numpy)" >&2
    "$python_for_venv" -m venv "$venv"
    "$venv/bin/pip" install --upgrade pip >&2
    "$venv/bin/pip" install bpy numpy >&2
fi

echo "building the release host and plugins (cargo xtask plugins --release)" >&2
cargo xtask plugins --release >&2

if [[ "${1:-}" == "--calibrate" ]]; then
    shift
    exec "$venv/bin/python" "$root/bench/blender/calibrate.py" "$@"
fi
exec "$venv/bin/python" "$root/bench/blender/compare.py" --command "bench/blender/blender.sh $*" "$@"
