#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ (one per reader) with clang, AddressSanitizer and
# UndefinedBehaviorSanitizer into build-fuzz/, then runs each on its seed corpus
# (fuzz/corpus/<target>/) for a bounded time. Fails if any target crashes, trips a sanitizer,
# leaks, hangs (10 s per input), allocates more than 2 GB or throws anything but a shine::Error.
#
#   scripts/run_fuzzers.sh [SECONDS_PER_TARGET] [TARGET...]   (default: 30 s, every target)
#
# Targets run one per core at a time (SHINE_FUZZ_JOBS overrides how many).
#
# Inputs found along the way are kept in build-fuzz/corpus/<target>/ (reused by the next run);
# a failing input is saved as build-fuzz/artifacts/<target>/crash-* (or leak-*, timeout-*, oom-*)
# and can be replayed with `build-fuzz/fuzz/<target> FILE`. Needs ShineVDB's own dependencies
# (scripts/setup.sh installs them); installs clang and libFuzzer when missing (Debian 12). The
# build is shared with `run_sanitizers.sh --readers` (scripts/clang_sanitized_build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/run_at_most.sh
. scripts/clang_sanitized_build.sh

seconds="${1:-30}"
[ $# -gt 0 ] && shift
all_targets=(fuzz_kitti_bin fuzz_poses fuzz_calib fuzz_tum fuzz_ply fuzz_pcd fuzz_point_cloud2
             fuzz_rosbag1 fuzz_mcap fuzz_rosbag2_sqlite fuzz_config_yaml fuzz_vdb fuzz_checkpoint
             fuzz_mover_tracks fuzz_camera_calibration fuzz_png fuzz_run_stats fuzz_exposure_record)
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=("${all_targets[@]}")
jobs="${SHINE_BUILD_JOBS:-$(nproc)}"

configure_clang_sanitized_build
cmake --build build-fuzz --target "${targets[@]}" -j"$jobs"

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
# UBSan checks are built recoverable so that the suppressions (known reports in third-party
# headers) apply; halt_on_error makes every other report fatal.
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1:suppressions=$PWD/fuzz/ubsan_suppressions.txt}"
# Leaks inside OpenVDB's reader on damaged files (not ours) are listed in lsan_suppressions.txt.
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$PWD/fuzz/lsan_suppressions.txt:print_suppressions=0}"
# One target per core at a time (each is one process): the same seconds per target, in less
# wall time. Each writes its status beside its log; the summary is printed in target order.
fuzz_one() {
    local t="$1"
    local seeds="fuzz/corpus/$t" work="build-fuzz/corpus/$t" artifacts="build-fuzz/artifacts/$t"
    local log="build-fuzz/$t.log"
    mkdir -p "$work" "$artifacts"
    # New inputs go to the first directory; the committed seeds stay untouched.
    if "build-fuzz/fuzz/$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
        -print_final_stats=1 -artifact_prefix="$artifacts/" "$work" "$seeds" >"$log" 2>&1; then
        echo ok >"build-fuzz/$t.status"
    else
        echo FAILED >"build-fuzz/$t.status"
    fi
}
parallel_runs="${SHINE_FUZZ_JOBS:-$jobs}"
echo "run_fuzzers: ${#targets[@]} targets for ${seconds} s each, ${parallel_runs} at a time"
for t in "${targets[@]}"; do rm -f "build-fuzz/$t.status"; done
run_at_most "$parallel_runs" fuzz_one "${targets[@]}"
failed=()
summary=()
for t in "${targets[@]}"; do
    status=$(cat "build-fuzz/$t.status" 2>/dev/null || echo FAILED)
    if [ "$status" != ok ]; then
        failed+=("$t")
        echo "run_fuzzers: $t failed; the end of build-fuzz/$t.log:"
        tail -n 40 "build-fuzz/$t.log" || true
    fi
    runs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "build-fuzz/$t.log" | grep -o '[0-9]*$' || echo "?")
    summary+=("$(printf '%-18s %-6s %10s executions' "$t" "$status" "$runs")")
done

printf '%s\n' "${summary[@]}"
if [ ${#failed[@]} -gt 0 ]; then
    echo "run_fuzzers: ${failed[*]} failed; inputs in build-fuzz/artifacts/, logs in build-fuzz/*.log" >&2
    exit 1
fi
echo "run_fuzzers: no failures"
