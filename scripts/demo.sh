#!/usr/bin/env bash
# Bakes the bundled demo scene end to end: installs what is missing, builds, starts a
# probebake-server on a free loopback port with a fresh data folder, submits
# tests/data/demo/demo-gltf.json with the probebake CLI (uploading its glTF level, the files it
# references and the sky as blobs), waits, fetches the volume, inspects it and renders two
# irradiance slices and a 3D view. Outputs go to $OUT_DIR (default: out/).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
BIN=${BUILD_DIR:-build}/bin
OUT=${OUT_DIR:-out}
mkdir -p "$OUT"

WORK=$(mktemp -d)
SERVER_PID=
cleanup() {
  if [ -n "$SERVER_PID" ]; then
    kill -TERM "$SERVER_PID" 2>/dev/null || true
    wait "$SERVER_PID" 2>/dev/null || true
  fi
  rm -rf "$WORK"
}
trap cleanup EXIT

"$BIN/probebake-server" --listen 127.0.0.1:0 --port-file "$WORK/port" --data-dir "$WORK/data" \
  2> "$OUT/demo-server.log" &
SERVER_PID=$!
for _ in $(seq 200); do
  [ -s "$WORK/port" ] && break
  kill -0 "$SERVER_PID" 2>/dev/null || { cat "$OUT/demo-server.log" >&2; exit 1; }
  sleep 0.05
done
SERVER=127.0.0.1:$(cat "$WORK/port")
echo "demo: probebake-server listening on $SERVER (log: $OUT/demo-server.log)"

"$BIN/probebake" submit tests/data/demo/demo-gltf.json --server "$SERVER" -o "$OUT/demo.vdb"
"$BIN/probebake" inspect "$OUT/demo.vdb"
"$BIN/probebake" inspect "$OUT/demo.vdb" --slice z=1.0 -o "$OUT/demo-slice-z1.png"
"$BIN/probebake" inspect "$OUT/demo.vdb" --slice x=0.0 -o "$OUT/demo-slice-x0.png"
"$BIN/probebake" view "$OUT/demo.vdb" --scene tests/data/demo/demo-gltf.json -o "$OUT/demo.html"

cat <<MSG

demo: done.
  probe volume:     $OUT/demo.vdb  (OpenVDB; 'probebake inspect $OUT/demo.vdb', or pyopenvdb)
  irradiance slices: $OUT/demo-slice-z1.png (horizontal, 1 m above the floor, facing up)
                     $OUT/demo-slice-x0.png (vertical, through the room's middle, facing +x)
  3D view:           $OUT/demo.html (open in a browser; docs/engines.md)
MSG
