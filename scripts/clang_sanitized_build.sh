# Sourced by run_fuzzers.sh and run_sanitizers.sh --readers: configures build-fuzz/, one clang
# build with AddressSanitizer, UndefinedBehaviorSanitizer and libFuzzer's coverage
# instrumentation (-fsanitize=fuzzer-no-link) of every library, for both the fuzz targets and
# the readers' test programs. One build serves both checks: CI compiled the libraries twice
# before (gcc for the tests, clang for the fuzzers; 6 and 7.5 minutes on 2 cores), and the tests
# now add 2.4 minutes to the fuzzers' build. The coverage instrumentation only adds counters: a
# test program links no libFuzzer and runs as it would without it.
#
#   configure_clang_sanitized_build   (installs clang and libclang-rt-14-dev when missing)

configure_clang_sanitized_build() {
    # clang and its libFuzzer runtime (libclang_rt.fuzzer-x86_64.a is in libclang-rt-14-dev).
    local extra_packages=(clang libclang-rt-14-dev) missing=() p
    for p in "${extra_packages[@]}"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
            missing+=("$p")
    done
    if [ ${#missing[@]} -gt 0 ]; then
        echo "installing ${missing[*]} (the sanitized clang build)"
        local sudo=""
        [ "$(id -u)" -ne 0 ] && sudo="sudo"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
            "${missing[@]}"
    fi
    # -O1 -g1 (line tables), as libFuzzer's documentation builds: reports still name file and
    # line, and the build is much shorter than with -O2 -g.
    CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
        -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
        -DSHINE_BUILD_FUZZERS=ON -DSHINE_BUILD_TESTS=ON \
        -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer" \
        >/dev/null
}
