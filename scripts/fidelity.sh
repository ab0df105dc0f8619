#!/usr/bin/env bash
# Fidelity table: voxoct (default and --thesis) and Open3D's TSDF fusion side by side on every
# development scan, judged by ../shared/bench/evalmesh.py, printed and written into README.md and
# BENCHMARKS.md between their `<!-- fidelity:begin -->` and `<!-- fidelity:end -->` markers.
#
#   PY=/path/to/venv/python scripts/fidelity.sh [SCAN_DIR...]
#
# Needs ../shared (the scans with their ground truth and the judge scripts), a Python with
# open3d-cpu, trimesh, manifold3d, scipy, rtree and pymeshlab, and admesh and prusa-slicer
# (see the README). The meshes are written in the platform frame (`--up y`), the frame of the
# ground truth.
set -euo pipefail
cd "$(dirname "$0")/.."
bench=../shared/bench
[ -d "$bench" ] || { echo "fidelity.sh: needs ../shared/bench beside the repository" >&2; exit 2; }
if [ $# -eq 0 ]; then set -- ../shared/data/*-scan; fi
cargo build --release --example scan -q
bin=target/release/examples/scan
up="--up y"
out=$(mktemp)
{
  echo '```text'
  "$bench/fidelity_table.sh" "$bin" default "$up" "$@"
  "$bench/fidelity_table.sh" "$bin" thesis "--thesis $up" "$@" | tail -n +2
  "$bench/fidelity_table.sh" o3d open3d "" "$@" | tail -n +2
  echo '```'
} | tee "$out"
for doc in README.md BENCHMARKS.md; do
  [ -f "$doc" ] && grep -q '<!-- fidelity:begin -->' "$doc" || continue
  awk -v f="$out" '
    /<!-- fidelity:begin -->/ { print; while ((getline l < f) > 0) print l; skip = 1; next }
    /<!-- fidelity:end -->/ { skip = 0 }
    !skip' "$doc" > "$doc.tmp" && mv "$doc.tmp" "$doc"
done
rm -f "$out"
