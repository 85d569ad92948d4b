#!/usr/bin/env bash
# Builds probebake with AddressSanitizer and UndefinedBehaviorSanitizer (-DPROBEBAKE_SANITIZE=ON,
# GCC) into build-sanitize/ and runs the test suite under them; any finding fails its test.
#   bash scripts/sanitize.sh              the whole suite
#   bash scripts/sanitize.sh -R REGEX     only the tests ctest -R selects
#   SANITIZE_TARGETS="a b" bash scripts/sanitize.sh -R REGEX
#                                         build only those targets first (CI's subset)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build-sanitize}
bash scripts/install-deps.sh
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPROBEBAKE_SANITIZE=ON \
  -DPROBEBAKE_BUILD_BENCHMARKS=OFF
if [ -n "${SANITIZE_TARGETS:-}" ]; then
  # shellcheck disable=SC2086  # a list of target names
  cmake --build "$BUILD_DIR" -j"$(nproc)" --target $SANITIZE_TARGETS
else
  cmake --build "$BUILD_DIR" -j"$(nproc)"
fi
# Leaks are reported too; halt on the first UBSan finding with its stack.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:detect_stack_use_after_return=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
ctest --test-dir "$BUILD_DIR" --output-on-failure -j"$(nproc)" --timeout 1800 "$@"
