#!/usr/bin/env bash
# make fuzz: replay the kept regression inputs, fuzz each target for FUZZ_SECONDS, then measure the
# source coverage the corpus reaches with an instrumented replay. Usage: run.sh BUILD_DIR SECONDS
# (BUILD_DIR holds the fuzz build, BUILD_DIR-coverage the coverage build). Fails when a target
# crashes, leaks, hangs or aborts on a differential check; the input is left in BUILD_DIR/artifacts.
set -euo pipefail
build=$1 seconds=$2
root=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$build/artifacts"
export LSAN_OPTIONS=suppressions=$root/native/fuzz/leak_suppressions.txt
for target in read_vdb render shaded; do
    binary=$build/fuzz/fuzz_$target corpus=$build/corpus/$target
    mkdir -p "$corpus"
    regressions=("$root"/tests/fuzz_regressions/$target/*)
    if [ -e "${regressions[0]}" ]; then
        echo "== fuzz_$target: the kept regressions"
        "$binary" -runs=1 "${regressions[@]}" 2>&1 | tail -1
    fi
    echo "== fuzz_$target: $seconds s"
    # -timeout: a render that has not returned in 20 s hangs; -rss_limit_mb: memory is bounded.
    "$binary" -max_total_time="$seconds" -timeout=20 -rss_limit_mb=4096 -max_len=200000 -print_final_stats=1 \
        -artifact_prefix="$build/artifacts/$target-" "$corpus" "$build/seeds/$target" > "$build/$target.log" 2>&1 ||
        { tail -40 "$build/$target.log"; exit 1; }
    grep -E "^#[0-9]+ +DONE|stat::number_of_executed_units|stat::peak_rss_mb" "$build/$target.log" | tail -3
done

echo "== coverage of the corpora (line coverage of the core, from an instrumented replay)"
profiles=$build-coverage/profiles
rm -rf "$profiles" && mkdir -p "$profiles"
for target in read_vdb render shaded; do
    LLVM_PROFILE_FILE="$profiles/$target-%p.profraw" "$build-coverage/fuzz/fuzz_$target" -runs=0 \
        "$build/corpus/$target" "$build/seeds/$target" > /dev/null 2>&1
done
llvm-profdata-14 merge -sparse "$profiles"/*.profraw -o "$profiles/merged.profdata"
llvm-cov-14 report "$build-coverage/fuzz/fuzz_read_vdb" -object "$build-coverage/fuzz/fuzz_render" \
    -object "$build-coverage/fuzz/fuzz_shaded" -instr-profile="$profiles/merged.profdata" \
    "$root"/native/src "$root"/native/include | tee "$build/coverage.txt"
# The shaded renderer's sources as fuzz_shaded's corpus alone reaches them.
llvm-profdata-14 merge -sparse "$profiles"/shaded-*.profraw -o "$profiles/shaded.profdata"
llvm-cov-14 report "$build-coverage/fuzz/fuzz_shaded" -instr-profile="$profiles/shaded.profdata" \
    "$root"/native/src/shaded "$root"/native/src/splat/slab_footprint.{cpp,h} "$root"/native/src/view/tile_set.{cpp,h} \
    "$root"/native/include/pcvr/{shaded,transfer_function,shading}.h | tee "$build/coverage-shaded.txt"
