#!/usr/bin/env bash
# Nucleus against the peer cloth solvers on the "drape" scene: builds the release host and
# plugins, creates the peers' Python environment when --live asks for it, and runs
# bench/peers.py (every option is documented in bench/README.md and by --help).
#
#   bench/peers.sh                                   # ours live at N = 32, 64, 128; peers recorded
#   bench/peers.sh --live --live-configs pypbd_pbd --live-N 64   # plus pypbd run live at N = 64
#   bench/peers.sh --peers /path/to/peers --N 64 --threads 1
#
# The peers' directory (default ../shared/peers from the repo root) is only read. Their Python
# environment goes to target/peers-venv (override with --venv DIR), their Warp kernel cache and
# our run outputs to target/peers/. Nothing here is needed by the test suite.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

venv="$root/target/peers-venv"
live=0
build=1
args=("$@")
for ((k = 0; k < ${#args[@]}; k++)); do
    case "${args[k]}" in
        --live) live=1 ;;
        --venv) venv="${args[k + 1]:-$venv}" ;;
        --venv=*) venv="${args[k]#--venv=}" ;;
        --tables-only | --no-ours | -h | --help) build=0 ;;
    esac
done

if [[ $build == 1 ]]; then
    echo "building the release host and plugins (cargo xtask plugins --release)" >&2
    cargo xtask plugins --release >&2
fi

if [[ $live == 1 && ! -x "$venv/bin/python" ]]; then
    echo "creating the peers' Python environment in $venv (pip, a few minutes)" >&2
    python3 -m venv "$venv"
    "$venv/bin/pip" install --upgrade pip >&2
    "$venv/bin/pip" install pypbd warp-lang newton mujoco numpy >&2
fi

# The metrics need only the standard library; the venv's numpy makes them faster when present.
python=python3
if [[ -x "$venv/bin/python" ]]; then
    python="$venv/bin/python"
fi
exec "$python" "$root/bench/peers.py" --venv "$venv" --command "bench/peers.sh $*" "$@"
