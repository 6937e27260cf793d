#!/usr/bin/env bash
# Runs every cargo-fuzz target for SECONDS (default 60) each, one after the other, on its corpus in
# fuzz/corpus/TARGET (new inputs found are added there; minimise with `cargo fuzz cmin TARGET`).
# A crash, a panic, a single allocation over 1 GiB (-malloc_limit_mb) or an RSS over 2 GiB is a
# finding: libFuzzer stops and writes the input to fuzz/artifacts/TARGET/.
#
#   scripts/fuzz.sh            # every target, 60 s each
#   scripts/fuzz.sh 300 pfm    # one target, 5 minutes
#
# Needs `cargo install cargo-fuzz`. Only a stable toolchain? RUSTC_BOOTSTRAP=1 lets it use the
# nightly-only sanitizer flags (set below); with SANITIZER=none the targets build without
# AddressSanitizer. Not part of CI.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
seconds="${1:-60}"
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(pfm calib discover image)
fi
export RUSTC_BOOTSTRAP=1
sanitizer="${SANITIZER:-address}"
cargo fuzz build -O --sanitizer "$sanitizer"
mkdir -p logs
for target in "${targets[@]}"; do
    mkdir -p "corpus/$target"
    echo "== $target: ${seconds}s"
    cargo fuzz run -O --sanitizer "$sanitizer" "$target" "corpus/$target" -- \
        -max_total_time="$seconds" -rss_limit_mb=2048 -malloc_limit_mb=1024 -max_len=65536 \
        -print_final_stats=1 2>&1 | tee "logs/$target.log" | grep -E '^#[0-9]+.*(DONE|pulse)|^(stat::|SUMMARY|==[0-9]+==ERROR)|panicked' || true
    tail -n 20 "logs/$target.log" | grep -E '^#[0-9]+ +DONE|stat::number_of_executed_units|stat::peak_rss' || true
done
