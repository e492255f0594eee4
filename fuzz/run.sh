#!/usr/bin/env bash
# Fuzzes each named target (default: all) for SECONDS (default 1200) from the seed corpus,
# then prints each target's executions and findings. Usage: fuzz/run.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-1200}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(ply obj pcd las laz copc e57 text scene)
[ -d corpus ] || cargo run --release --example seed -- ../../shared/data
cargo +nightly fuzz build -O -s none
mkdir -p logs
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t"
  # -malloc_limit_mb: one allocation past 1 GiB from inputs of at most 64 KiB is a finding.
  # Fork mode with the ignore flags runs the whole time and keeps every finding.
  cargo +nightly fuzz run -O -s none "$t" "corpus/$t" -- \
    -max_total_time="$seconds" -max_len=65536 -timeout=10 \
    -rss_limit_mb=2048 -malloc_limit_mb=1024 \
    -fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 \
    >"logs/$t.log" 2>&1 || true
  runs=$(grep -o '^#[0-9]*' "logs/$t.log" | tail -1 | tr -d '#')
  echo "$t: ${runs:-?} executions in ${seconds} s, $(ls "artifacts/$t" 2>/dev/null | wc -l) findings"
done
