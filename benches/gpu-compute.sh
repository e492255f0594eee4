#!/usr/bin/env bash
# The compute-rasterizer speed study on a lent GPU machine, from the repository root after
# `bash ../shared/gpu/stage.sh` (run with carry [".gl", ".gpu"]):
#   source .gpu/on-device.sh && bash benches/gpu-compute.sh
# Samples POINTS (default 100 M) points from the staged dragon, runs the CUDA anchor
# (../shared/gpu/anchor.py) and `surfel render --timings` for every point method at
# 1920x1080 on the same file, and writes everything under $OUT (or ./gpu-compute).
set -euo pipefail
out=${OUT:-gpu-compute}
points=${POINTS:-100000000}
mkdir -p "$out"
cloud=/tmp/surfel-gpu-cloud.ply
.gpu/surfel sample .gpu/dragon_vrip_res2.ply --points "$points" --out "$cloud"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$out/device.txt"
ANCHOR_OUT="$out" python3 .gpu/anchor.py "$cloud" | tee "$out/anchor.txt"
for method in compute compute:quantized=0 compute-hq points; do
  .gpu/surfel render "$cloud" --method "$method" --size 1920x1080 --frames 50 \
    --timings "$out/$method.json" --out "$out/$method.png" 2>&1 | tee -a "$out/surfel.txt"
done
