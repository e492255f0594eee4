#!/usr/bin/env bash
# What the viewer's clipping box and class filter cost in the projection passes, on a lent GPU
# machine (from the repository root after `bash ../shared/gpu/stage.sh`, run with carry
# [".gl", ".gpu"]):
#   source .gpu/on-device.sh && bash benches/gpu-filter.sh
# or on this machine's lavapipe with SURFEL=target/release/surfel POINTS=1000000.
# Samples POINTS (default 30 M) points from the staged dragon, adds a classification column
# (classes 0-7 by point index), and renders every METHODS entry at 1920x1080 with no filter,
# a clipping box keeping about half the points, four of eight classes hidden, and both;
# writes the timings and images under $OUT (or ./gpu-filter).
set -euo pipefail
out=${OUT:-gpu-filter}
points=${POINTS:-30000000}
surfel=${SURFEL:-.gpu/surfel}
dragon=${DRAGON:-.gpu/dragon_vrip_res2.ply}
methods=${METHODS:-compute points pyramid}
frames=${FRAMES:-50}
mkdir -p "$out"
sampled=/tmp/surfel-filter-sampled.ply
cloud=/tmp/surfel-filter-cloud.ply
"$surfel" sample "$dragon" --points "$points" --out "$sampled"
python3 - "$sampled" "$cloud" <<'EOF'
import sys
import numpy as np
src, dst = sys.argv[1], sys.argv[2]
data = open(src, "rb").read()
end = data.index(b"end_header\n") + len(b"end_header\n")
header = data[:end].decode()
n = int(next(l.split()[2] for l in header.splitlines() if l.startswith("element vertex")))
floats = sum(1 for l in header.splitlines() if l.startswith("property float"))
v = np.frombuffer(data, dtype=np.float32, count=n * floats, offset=end).reshape(n, floats)
out = np.zeros(n, dtype=[("f", np.float32, floats), ("c", np.uint8)])
out["f"] = v
out["c"] = (np.arange(n) % 8).astype(np.uint8)
with open(dst, "wb") as f:
    f.write(header.replace("end_header\n", "property uchar classification\nend_header\n").encode())
    f.write(out.tobytes())
EOF
rm -f "$sampled"
cat > "$out/none.toml" <<'EOF'
EOF
# The dragon spans about x -0.095..0.061, y 0.033..0.187, z -0.044..0.044: the box keeps the
# half with x below -0.017.
cat > "$out/clip.toml" <<'EOF'
[clip]
centre = [-0.06, 0.11, 0.0]
half = [0.043, 0.1, 0.1]
EOF
cat > "$out/classes.toml" <<'EOF'
hidden_classes = [0, 2, 4, 6]
EOF
cat > "$out/both.toml" <<'EOF'
hidden_classes = [0, 2, 4, 6]
[clip]
centre = [-0.06, 0.11, 0.0]
half = [0.043, 0.1, 0.1]
EOF
(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || echo lavapipe) | tee "$out/device.txt"
for method in $methods; do
  for filter in none clip classes both; do
    "$surfel" render "$cloud" --method "$method" --size 1920x1080 --frames "$frames" \
      --scene "$out/$filter.toml" --timings "$out/$method-$filter.json" \
      --out "$out/$method-$filter.png" 2>&1 | tee -a "$out/surfel.txt"
  done
done
rm -f "$cloud"
