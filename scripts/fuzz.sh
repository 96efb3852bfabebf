#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) into build-fuzz/ and runs each for a
# bounded time on its seed corpus (see fuzz/CMakeLists.txt for the targets).
#   scripts/fuzz.sh            # 60 s per target
#   scripts/fuzz.sh 20         # 20 s per target (what CI runs)
#   scripts/fuzz.sh 600 mesh   # one target
# Seeds: fuzz/corpus/<target>, configs/*.pbtxt (scene), configs/probes (probe_script) and the
# regression inputs in tests/data/fuzz-regressions/<target>. New coverage goes to
# build-fuzz/corpus/<target>; a crash, leak, timeout or out-of-memory leaves its input in
# build-fuzz/artifacts/ and fails the script: add it to tests/data/fuzz-regressions/<target>/
# (replayed by the fuzz_regressions_<target> tests) together with the fix.
# Needs the packages of scripts/setup.sh; installs clang and the compiler runtime itself.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH=${1:-60}
shift || true
TARGETS=("$@")
((${#TARGETS[@]})) || TARGETS=(client_message mesh scene probe_script)
BUILD_DIR=${FUZZ_BUILD_DIR:-build-fuzz}
JOBS=${JOBS:-$(nproc)}

PACKAGES=(clang libclang-rt-14-dev)
source scripts/apt-ensure.sh
apt_ensure fuzz "${PACKAGES[@]}"

CXX=clang++ CC=clang cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCONICA_FUZZ=ON -DCONICA_BUILD_TESTS=OFF -DCONICA_BUILD_BENCH=OFF -DCONICA_NATIVE=OFF >/dev/null
cmake --build "$BUILD_DIR" -j"$JOBS" --target "${TARGETS[@]/#/conica-fuzz-}"

declare -A SEEDS=([scene]="configs" [probe_script]="configs/probes")
declare -A MAXLEN=([client_message]=4096 [mesh]=16384 [scene]=8192 [probe_script]=8192)
mkdir -p "$BUILD_DIR/artifacts"
status=0
for t in "${TARGETS[@]}"; do
  work="$BUILD_DIR/corpus/$t"
  mkdir -p "$work"
  dirs=("$work" "fuzz/corpus/$t")
  [[ -n "${SEEDS[$t]:-}" ]] && dirs+=("${SEEDS[$t]}")
  [[ -d "tests/data/fuzz-regressions/$t" ]] && dirs+=("tests/data/fuzz-regressions/$t")
  echo "fuzz: $t for ${SECONDS_EACH} s"
  log="$BUILD_DIR/artifacts/$t.log"
  # -timeout: one input longer than 60 s is a hang (the largest body a scene may generate,
  # 100,000 lattice cells, takes about 20 s to build under this instrumentation: 296,000 cells
  # took 68 s); -rss_limit_mb: more than 2 GiB is a finding.
  if ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 \
     "$BUILD_DIR/bin/conica-fuzz-$t" -max_total_time="$SECONDS_EACH" -timeout=60 \
       -rss_limit_mb=2048 -max_len="${MAXLEN[$t]}" -print_final_stats=1 \
       -artifact_prefix="$BUILD_DIR/artifacts/$t-" "${dirs[@]}" >"$log" 2>&1; then
    grep -E "^(stat::number_of_executed_units|stat::peak_rss_mb)|INITED|DONE" "$log" | tr '\n' ' '
    echo
  else
    status=1
    echo "fuzz: $t FAILED; input and log in $BUILD_DIR/artifacts/ ($t-*):"
    grep -E "ERROR|SUMMARY|Test unit written|==[0-9]+==" "$log" | head -20
  fi
done
exit $status
