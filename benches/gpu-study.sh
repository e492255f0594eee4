#!/usr/bin/env bash
# The GPU study on a lent H100/H200 machine, from the repository root after
# `bash ../shared/gpu/stage.sh` (run with carry [".gl", ".gpu"]), in under 8 minutes:
#   source .gpu/on-device.sh && OUT=docs/reports/h100-study bash benches/gpu-study.sh
# (a) `surfel render --timings` of `compute` and `points` at 1920x1080 on the staged dragon
#     sampled to 10 M and 100 M points, beside the CUDA anchor (../shared/gpu/anchor.py);
# (b) `surfel bench --report` of one method per family on the dragon sampled to 5 M points at
#     1024x1024, scored against the `mesh` ground truth with per-pass GPU times (the bench
#     also runs every method on the dragon mesh's own vertices: its baseline, which holds the
#     `mesh` record), still at the default pose and along the camera path
#     benches/paths/orbit-zoom.toml (every frame timed; its chart and table in the report).
# Order: the 10 M runs, the bench, then the 100 M runs (minutes of sampling and loading), so a
# slow machine loses the largest cloud first. Every step runs under the time budget; a step
# that would start after it is skipped, one still running at its end is stopped, and both are
# recorded in steps.tsv. The exit status is 1 when a surfel step failed or was skipped.
#
# Output under $OUT (default ./gpu-study), laid out like docs/reports/<gpu>/:
#   device.txt        nvidia-smi (when present) and surfel's Vulkan device report
#   anchor.txt        the CUDA anchor's output, or why it did not run; anchor_N.json from it
#   timings/M-N.json  `surfel render --timings` of method M on N points (images/M-N.png):
#                     run metadata, every frame's samples, medians with 95 % intervals;
#                     M-N.csv the samples as a tidy table, M-N.trace.json a Perfetto trace
#   bench/            sweep.toml, results.json, results.csv, report.md, charts/
#   surfel.txt        everything surfel printed; steps.tsv: step, status, seconds
#   study.md          a summary of the above
#
# Environment (defaults for the GPU machine, then for the dry run):
#   GPU_STUDY_DRY=1         dry run on lavapipe for CI: small sizes, validation layers on,
#                           the binary and data of the build machine, no nvidia-smi or anchor
#   SURFEL_BIN              .gpu/surfel | target/release/surfel
#   GPU_STUDY_MESH          .gpu/dragon_vrip_res2.ply | ../shared/data/stanford/dragon_vrip_res2.ply
#   GPU_STUDY_POINTS        "10000000 100000000" | "20000 50000"   (a): cloud sizes
#   GPU_STUDY_SIZE          1920x1080 | 128x128                     (a): image size
#   GPU_STUDY_FRAMES        50 | 5                                  (a): timed frames
#   GPU_STUDY_METHODS       "compute points"                        (a): methods
#   GPU_STUDY_BENCH_POINTS  5000000 | 20000                         (b): cloud size
#   GPU_STUDY_BENCH_SIZE    1024x1024 | 128x128                     (b): image size
#   GPU_STUDY_BENCH_FRAMES  "10 50" | "1 3"                         (b): warm-up and timed frames
#   GPU_STUDY_PATH_FRAMES   60 | 4                                  (b): frames along the path
#   GPU_STUDY_BENCH_METHODS points compute compute-hq perspective-deferred affine-flat ewa
#                           pyramid kernel5 hpr lod-compute lod-mesh mesh
#   GPU_STUDY_BUDGET_S      450 | 300                               seconds for all steps
set -euo pipefail

if [[ ! -f benches/gpu-study.sh ]]; then
  echo "gpu-study: run from the repository root" >&2
  exit 2
fi

dry=${GPU_STUDY_DRY:-0}
if [[ $dry == 1 ]]; then
  bin=${SURFEL_BIN:-target/release/surfel}
  mesh=${GPU_STUDY_MESH:-../shared/data/stanford/dragon_vrip_res2.ply}
  counts=${GPU_STUDY_POINTS:-20000 50000}
  size=${GPU_STUDY_SIZE:-128x128}
  frames=${GPU_STUDY_FRAMES:-5}
  bench_points=${GPU_STUDY_BENCH_POINTS:-20000}
  bench_size=${GPU_STUDY_BENCH_SIZE:-128x128}
  bench_frames=${GPU_STUDY_BENCH_FRAMES:-1 3}
  path_frames=${GPU_STUDY_PATH_FRAMES:-4}
  budget=${GPU_STUDY_BUDGET_S:-300}
  validation=(--validation)
  mode="; dry run, validation layers on"
else
  bin=${SURFEL_BIN:-.gpu/surfel}
  mesh=${GPU_STUDY_MESH:-.gpu/dragon_vrip_res2.ply}
  counts=${GPU_STUDY_POINTS:-10000000 100000000}
  size=${GPU_STUDY_SIZE:-1920x1080}
  frames=${GPU_STUDY_FRAMES:-50}
  bench_points=${GPU_STUDY_BENCH_POINTS:-5000000}
  bench_size=${GPU_STUDY_BENCH_SIZE:-1024x1024}
  bench_frames=${GPU_STUDY_BENCH_FRAMES:-10 50}
  path_frames=${GPU_STUDY_PATH_FRAMES:-60}
  budget=${GPU_STUDY_BUDGET_S:-450}
  validation=()
  mode=""
fi
methods=${GPU_STUDY_METHODS:-compute points}
bench_methods=${GPU_STUDY_BENCH_METHODS:-points compute compute-hq perspective-deferred \
affine-flat ewa pyramid kernel5 hpr lod-compute lod-mesh mesh}
read -r bench_warmup bench_measured <<<"$bench_frames"

out=${OUT:-gpu-study}
mkdir -p "$out/timings" "$out/images" "$out/bench"
: >"$out/surfel.txt"
printf 'step\tstatus\tseconds\n' >"$out/steps.tsv"
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
clouds=$(mktemp -d "${TMPDIR:-/tmp}/surfel-gpu-study.XXXXXX")
trap 'rm -rf "$clouds"' EXIT

start=$SECONDS
failed=0

# step NAME LOG REQUIRED CMD...: runs CMD under the time left, its output appended to LOG and
# printed, and records NAME's status (exit code, "timeout" or "skipped") and seconds. A failure
# counts against the exit status when REQUIRED is 1. Returns CMD's status (1 when skipped).
step() {
  local name=$1 log=$2 required=$3
  shift 3
  local left=$((budget - (SECONDS - start)))
  if ((left <= 0)); then
    printf '%s\tskipped (budget of %s s spent)\t0\n' "$name" "$budget" >>"$out/steps.tsv"
    echo "gpu-study: $name skipped, the budget of $budget s is spent" | tee -a "$log" >&2
    ((required)) && failed=$((failed + 1))
    return 1
  fi
  local t0=$SECONDS rc status
  echo "== $name: $*" | tee -a "$log"
  set +e
  timeout -k 10 "$left" "$@" 2>&1 | tee -a "$log"
  rc=${PIPESTATUS[0]}
  set -e
  status=$rc
  if ((rc == 124 || rc == 137)); then status="timeout (budget of $budget s)"; fi
  printf '%s\t%s\t%s\n' "$name" "$status" "$((SECONDS - t0))" >>"$out/steps.tsv"
  if ((rc != 0)); then
    echo "gpu-study: $name failed ($status)" >&2
    ((required)) && failed=$((failed + 1))
  fi
  return "$rc"
}

# The device: nvidia-smi on the GPU machine, and the Vulkan device surfel sees.
{
  if [[ $dry != 1 ]] && command -v nvidia-smi >/dev/null; then
    nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv
  fi
  "$bin" info "$mesh" | sed -n '/^device /,$p'
} >"$out/device.txt"
cat "$out/device.txt"

anchor=1
if [[ $dry == 1 ]]; then
  echo "anchor: not run (dry run)" >"$out/anchor.txt"
  anchor=0
elif ! python3 -c 'import cupy' >"$clouds/cupy.txt" 2>&1; then
  { echo "anchor: not run, CuPy does not import:"; cat "$clouds/cupy.txt"; } >"$out/anchor.txt"
  anchor=0
else
  : >"$out/anchor.txt"
fi

# (a) for one cloud size: sample, render every method with timings, then the anchor.
study_size() {
  local n=$1 cloud=$clouds/dragon-$1.ply m file
  step "sample $n" "$out/surfel.txt" 1 "$bin" sample "$mesh" --points "$n" --out "$cloud" ||
    return 0
  for m in $methods; do
    file=${m//[:,=]/-}-$n
    step "render $m $n" "$out/surfel.txt" 1 "$bin" render "$cloud" --method "$m" \
      --size "$size" --frames "$frames" --timings "$out/timings/$file.json" \
      --timings-csv "$out/timings/$file.csv" --trace "$out/timings/$file.trace.json" \
      --out "$out/images/$file.png" "${validation[@]}" || true
  done
  if ((anchor)); then
    step "anchor $n" "$out/anchor.txt" 0 env ANCHOR_OUT="$out" python3 .gpu/anchor.py "$cloud" ||
      true
  fi
  rm -f "$cloud"
}

# (b) the method families on one sampled dragon, scored against the mesh.
study_bench() {
  local sweep=$out/bench/sweep.toml m
  local model
  model=$(cd "$(dirname "$mesh")" && pwd)/$(basename "$mesh")
  {
    echo "# Written by benches/gpu-study.sh: one method per family on the dragon sampled to"
    echo "# $bench_points points (and on the mesh's own vertices, the baseline), against the mesh."
    echo "resolutions = [\"$bench_size\"]"
    echo "lights = [1]"
    echo
    echo "[frames]"
    echo "warmup = $bench_warmup"
    echo "measured = $bench_measured"
    echo
    echo "[[models]]"
    echo "name = \"dragon\""
    echo "path = \"$model\""
    echo "points = [$bench_points]"
    for m in $bench_methods; do
      echo
      echo "[[methods]]"
      echo "name = \"$m\""
    done
    echo
    echo "[[poses]]"
    echo "name = \"default\""
    echo
    echo "[[poses]]"
    echo "name = \"flight\""
    echo "path = \"flight.toml\""
  } >"$sweep"
  sed "s/^frames = .*/frames = $path_frames/" benches/paths/orbit-zoom.toml >"$out/bench/flight.toml"
  step "bench $bench_points" "$out/surfel.txt" 1 "$bin" bench "$sweep" --out "$out/bench" \
    --report "${validation[@]}" || true
}

read -r -a sizes <<<"$counts"
study_size "${sizes[0]}"
study_bench
for n in "${sizes[@]:1}"; do
  study_size "$n"
done

# The summary.
frame_ms() {
  awk '/"frame": \{/ { f = 1 } f && /"median_ms"/ { gsub(/[^0-9.eE+-]/, "", $2); print $2; exit }' "$1"
}
{
  echo "# surfel GPU study"
  echo
  echo "- Device: $(grep -m1 '^device ' "$out/device.txt" | sed 's/^device *//')"
  echo "- Date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
  echo "- Binary: $bin; model: $mesh$mode"
  echo "- Wall time: $((SECONDS - start)) s of a $budget s budget; steps: [steps.tsv](steps.tsv)"
  echo
  echo "## (a) \`surfel render --timings\`, $size, $frames frames"
  echo
  echo "| method | points | frame ms | G points/s | timings |"
  echo "|---|---|---|---|---|"
  for n in "${sizes[@]}"; do
    for m in $methods; do
      file=timings/${m//[:,=]/-}-$n.json
      if [[ -f $out/$file ]]; then
        ms=$(frame_ms "$out/$file")
        echo "| $m | $n | $(awk -v n="$n" -v ms="$ms" 'BEGIN {
          if (ms > 0) printf "%.3f | %.3f", ms, n / ms / 1e6; else print "? | ?" }') | [$file]($file) |"
      else
        echo "| $m | $n | – | – | missing |"
      fi
    done
  done
  echo
  echo "CUDA anchor: [anchor.txt](anchor.txt)."
  echo
  echo "## (b) \`surfel bench\`, $bench_size, $bench_points points"
  echo
  echo "Methods: $bench_methods. Report: [bench/report.md](bench/report.md)."
} >"$out/study.md"

echo "gpu-study: $((SECONDS - start)) s, $failed failed or skipped step(s); results in $out"
((failed == 0))
