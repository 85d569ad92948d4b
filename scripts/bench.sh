#!/usr/bin/env bash
# Regenerates the accuracy and speed benchmark (docs/accuracy-and-speed.md, tests/bench/README.md):
# installs the dependencies, builds probebake-bench into $BUILD_DIR (default build/) and runs it.
# The full run writes tests/bench/results/ (results.md, results.csv, results.json,
# adaptive_probes.csv, error_vs_time_<scene>.svg) and the figures README.md and
# docs/accuracy-and-speed.md embed, in about 5 minutes on an idle 2-core machine (references
# included; a loaded machine takes several times that), less once the reference bakes are cached
# (${XDG_CACHE_HOME:-~/.cache}/probebake-bench, keyed by job digest).
#
#   scripts/bench.sh              # full run
#   scripts/bench.sh --quick      # smoke check, ~1-2 minutes; reports in $BUILD_DIR/bench-work/quick-results
#   scripts/bench.sh --docs-only  # only rewrite the documents' figures from tests/bench/results/results.json
#
# Other arguments go to probebake-bench (--scenes demo,courtyard, --no-memory, --repeats N, ...).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
scripts/install-deps.sh
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD_DIR" --target probebake-bench probebake_bake_bench -j"$(nproc)"
echo "bench: load average before the run: $(cut -d' ' -f1-3 /proc/loadavg) (other work skews wall times)"
# Recorded in the report: the commit measured, "+local-changes" when the tree differs from it.
if commit=$(git rev-parse --short HEAD 2>/dev/null); then
  git diff --quiet HEAD 2>/dev/null || commit="$commit+local-changes"
  export PROBEBAKE_BENCH_COMMIT="$commit"
fi
exec "$BUILD_DIR/bin/probebake-bench" --source "$PWD" "$@"
