#!/usr/bin/env bash
# A live scan end to end without a Kinect or a turntable (issue 17):
#   1. record_fakenect writes the simulator's frames as a fakenect recording, in the order a
#      live scan consumes them, and the recorded scan that scan should capture (expected/);
#   2. turntable_server serves a simulated table on loopback;
#   3. `scan --kinect --kinect-depth raw` runs under libfreenect's fakenect library (the real
#      libfreenect_sync calls, replaying the recording) with --record-to;
#   4. checks: each snapshot captured and the table turned, the captured frames are the
#      expected ones byte for byte, the recorded scan re-processes (--input) to a byte-identical
#      STL, and the mesh is closed;
#   5. the real NYU Kinect frame (../shared/data/nyu-kinect-fakenect, skipped when absent):
#      the live path under fakenect and the --fakenect reader give the same mesh.
#
# Needs: the Debian package libfreenect0.5 (its fakenect library) and libfreenect-dev.
# Env: FAKENECT_LIB (directory of the fakenect libfreenect.so.0.5; found under /usr/lib by
# default), LIVE_SCAN_REQUIRED=1 (a missing fakenect library fails instead of skipping),
# KEEP=1 (keep the work directory).
set -euo pipefail
cd "$(dirname "$0")/.."

log() { printf 'live_scan: %s\n' "$*"; }
fail() { printf 'live_scan: FAIL: %s\n' "$*" >&2; exit 1; }

lib=${FAKENECT_LIB:-}
if [ -z "$lib" ]; then
  so=$(find /usr/lib /usr/local/lib -path '*/fakenect/libfreenect.so.0*' 2>/dev/null | sort | head -n 1 || true)
  [ -n "$so" ] && lib=$(dirname "$so")
fi
if [ -z "$lib" ] || ! ls "$lib"/libfreenect.so.0* >/dev/null 2>&1; then
  [ "${LIVE_SCAN_REQUIRED:-0}" = 1 ] && fail "no fakenect library (apt-get install libfreenect0.5)"
  log "SKIPPED: no fakenect library found (apt-get install libfreenect0.5)"
  exit 0
fi
log "fakenect library: $lib"

cargo build --release --features freenect --quiet \
  --example scan --example turntable_server --example record_fakenect
bin=target/release/examples

work=$(mktemp -d "${TMPDIR:-/tmp}/voxoct-live.XXXXXX")
server=""
cleanup() {
  if [ -n "$server" ]; then kill "$server" 2>/dev/null || true; wait "$server" 2>/dev/null || true; fi
  if [ "${KEEP:-0}" = 1 ]; then log "kept $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT

# The simulated turntable on loopback, on a port the system picks. Its log exists before it
# starts: the background job opens it only once it runs, which a loaded machine may delay past
# the first read below.
: >"$work/server.log"
"$bin/turntable_server" --listen 127.0.0.1:0 -v 2>"$work/server.log" &
server=$!
port=""
for _ in $(seq 300); do
  port=$(sed -n 's/.*listening on 127\.0\.0\.1:\([0-9]*\).*/\1/p' "$work/server.log")
  [ -n "$port" ] && break
  kill -0 "$server" 2>/dev/null || { cat "$work/server.log" >&2; fail "turntable_server died"; }
  sleep 0.1
done
[ -n "$port" ] || fail "turntable_server did not report its port"
log "turntable_server on 127.0.0.1:$port"

# Mesh settings: 2 mm leaves over a 0.5 m root (the clip box is 0.3 × 0.4 × 0.3 m).
mesh=(--leaf 0.002 --root 0.5)

# ---- 1-4: a generated recording, 4 snapshots × 3 frames ---------------------------------------
n=4 f=3
"$bin/record_fakenect" --out "$work/rec" --expected "$work/expected" \
  --snapshots $n --frames $f --interval-ms 400
live() { # live OUT_PREFIX RECORDING SCAN_ARGS...
  local out=$1 rec=$2; shift 2
  FAKENECT_PATH=$rec LD_LIBRARY_PATH=$lib \
    timeout 300 "$bin/scan" --kinect --kinect-depth raw --turntable "127.0.0.1:$port" \
    --out "$out.stl" --stats "$out.json" "$@" 2>&1 | tee "$out.log"
}
log "live scan under fakenect: $n snapshots × $f frames"
live "$work/live" "$work/rec" --snapshots $n --frames $f \
  --config "$work/expected/scan.toml" --record-to "$work/live-scan" "${mesh[@]}"

got=$(grep -c '^capture: snapshot [0-9]*/'"$n"' at .*: '"$f"' frames$' "$work/live.log" || true)
[ "$got" = "$n" ] || fail "$got of $n snapshots captured"
got=$(grep -c '^turntable: turned by ' "$work/live.log" || true)
[ "$got" = $((n - 1)) ] || fail "the table turned $got times, not $((n - 1))"
log "OK: $n snapshots captured, the table turned $((n - 1)) times"

# The frames the live path captured are those the recording holds for each snapshot, read by
# voxoct's own fakenect reader: same 16-bit PNGs, same manifest (angles from the table).
diff -r "$work/expected" "$work/live-scan" >"$work/diff.txt" 2>&1 ||
  { head -n 20 "$work/diff.txt" >&2; fail "captured frames differ from the recording's"; }
log "OK: the captured scan equals the recording frame for frame ($(ls "$work/live-scan/frames" | wc -l) frames)"

# Re-processing the recorded scan gives the same mesh, byte for byte.
"$bin/scan" --input "$work/live-scan" --out "$work/replay.stl" --stats "$work/replay.json" \
  "${mesh[@]}" 2>&1 | tee "$work/replay.log"
cmp "$work/live.stl" "$work/replay.stl" || fail "re-processing gave another STL"
grep -q '"closed_manifold": true' "$work/live.json" || fail "the live mesh is not closed"
tri=$(sed -n 's/.*"mesh_triangles": \([0-9]*\).*/\1/p' "$work/live.json")
vol=$(sed -n 's/.*"mesh_volume_m3": \([0-9.e-]*\).*/\1/p' "$work/live.json")
log "OK: re-processing --input gives a byte-identical STL ($tri triangles, $vol m³), closed"

# An independent check of closedness where python3 is present: every edge of the binary STL
# (vertices welded by exact coordinates) is shared by exactly two triangles, in opposite
# directions.
if command -v python3 >/dev/null; then
  python3 - "$work/live.stl" <<'PY'
import struct, sys, collections
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 80)[0]
assert len(data) == 84 + 50 * n, "truncated STL"
ids, edges = {}, collections.Counter()
for t in range(n):
    v = struct.unpack_from("<9f", data, 84 + 50 * t + 12)
    tri = [ids.setdefault(v[i:i + 3], len(ids)) for i in (0, 3, 6)]
    for a, b in ((0, 1), (1, 2), (2, 0)):
        edges[(tri[a], tri[b])] += 1
bad = [e for e, c in edges.items() if c != 1 or edges.get((e[1], e[0]), 0) != 1]
print(f"live_scan: STL {n} triangles, {len(ids)} vertices, {len(edges)} directed edges, {len(bad)} unmatched")
sys.exit(1 if bad else 0)
PY
  log "OK: every edge of the STL has exactly one opposite twin"
fi

# ---- 5: the single real NYU Kinect frame --------------------------------------------------------
nyu=../shared/data/nyu-kinect-fakenect
if [ ! -f "$nyu/INDEX.txt" ]; then
  log "NYU frame: SKIPPED ($nyu is absent)"
  exit 0
fi
# One frame is not enough under fakenect (opening the Kinect consumes one, and libfreenect 0.5's
# runloop stops at the end of INDEX.txt): the same frame five times, 400 ms apart.
frame=$(grep -m 1 '^d-' "$nyu/INDEX.txt")
mkdir "$work/nyu-rec"
for i in 0 1 2 3 4; do
  name="d-$((i * 4 / 10 + 1)).$((i * 4 % 10))00000-$((i * 400000)).pgm"
  cp "$nyu/$frame" "$work/nyu-rec/$name"
  echo "$name" >>"$work/nyu-rec/INDEX.txt"
done
# The room's scanner settings (the NYU toolbox's intrinsics, the camera at the origin looking
# along -Z, level; the clip box holds the room), shared with tests/room.rs and the figures.
cp examples/nyu-room.toml "$work/nyu.toml"
room=(--leaf 0.04 --root 16)
log "live scan of the real NYU frame under fakenect: 1 snapshot × 1 frame"
live "$work/nyu-live" "$work/nyu-rec" --snapshots 1 --frames 1 --config "$work/nyu.toml" \
  --record-to "$work/nyu-scan" "${room[@]}"
grep -q '^capture: snapshot 1/1 at 0°: 1 frames$' "$work/nyu-live.log" || fail "NYU snapshot not captured"
grep -q '"closed_manifold": true' "$work/nyu-live.json" || fail "the NYU mesh is not closed"
"$bin/scan" --fakenect "$nyu" --degrees-per-snapshot 0 --frames 1 --config "$work/nyu.toml" \
  --out "$work/nyu-reader.stl" "${room[@]}" 2>&1 | tee "$work/nyu-reader.log"
cmp "$work/nyu-live.stl" "$work/nyu-reader.stl" || fail "fakenect library and voxoct's reader disagree"
"$bin/scan" --input "$work/nyu-scan" --out "$work/nyu-replay.stl" "${room[@]}" -q
cmp "$work/nyu-live.stl" "$work/nyu-replay.stl" || fail "re-processing the NYU scan gave another STL"
tri=$(sed -n 's/.*"mesh_triangles": \([0-9]*\).*/\1/p' "$work/nyu-live.json")
log "OK: NYU frame: live under fakenect = --fakenect reader = re-processed, byte-identical ($tri triangles), closed"
