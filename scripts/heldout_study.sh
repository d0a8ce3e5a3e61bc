#!/usr/bin/env bash
# The held-out comparison of docs/heldout.md: ShineVDB (batch and incremental, 0.1 and 0.2 m) and
# the TSDF baseline run as VDBFusion runs (every point, truncation 3 voxels, no hole filling) on
# the same scans, each mapping all but every N-th scan and scored on those (shine eval --heldout's
# yardstick). Prints a Markdown table; every run's outputs stay in OUT/<name>/.
#   scripts/heldout_study.sh DATA OUT [N=3] [extra shine map arguments...]
# Example: scripts/heldout_study.sh ../shared/data/balm_realworld /tmp/heldout 3
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 2 ]; then
    echo "usage: scripts/heldout_study.sh DATA OUT [N=3] [extra shine map arguments...]" >&2
    exit 2
fi
data=$1
out=$2
every=${3:-3}
shift $(($# < 3 ? $# : 3))
shine=build/shine
[ -x "$shine" ] || { echo "heldout_study: build first (scripts/setup.sh)" >&2; exit 1; }
mkdir -p "$out"

run() {  # name, then the shine arguments
    local name=$1
    shift
    rm -rf "${out:?}/$name"
    "$shine" "$@" -o "$out/$name" --holdout-every "$every" --threads 2 -q --no-eval \
        > "$out/$name.log" 2>&1 || { echo "heldout_study: $name failed, see $out/$name.log" >&2; exit 1; }
}

run tsdf_0.1 tsdf "$data" --voxel-size-m 0.1 --trunc-m 0.3 --voxel-downsample-m 0
run tsdf_0.2 tsdf "$data" --voxel-size-m 0.2 --trunc-m 0.6 --voxel-downsample-m 0
run batch_0.2 map "$data" --leaf-size-m 0.2 "$@"
run batch_0.1 map "$data" --leaf-size-m 0.1 "$@"
run incremental_0.2 map "$data" --mode incremental --leaf-size-m 0.2 "$@"
run incremental_0.1 map "$data" --mode incremental --leaf-size-m 0.1 "$@"

/usr/bin/python3 - "$out" "$every" <<'EOF'
import json
import sys

out, every = sys.argv[1], sys.argv[2]
print(f"| map (held out: 1 scan in {every}) | rays within 10 cm | median error | mean error "
      "| rays that hit | map memory | seconds |")
print("| --- | --- | --- | --- | --- | --- | --- |")
for name in ["tsdf_0.1", "tsdf_0.2", "batch_0.2", "batch_0.1", "incremental_0.2",
             "incremental_0.1"]:
    stats = json.load(open(f"{out}/{name}/stats.json"))
    total = stats["heldout"]["total"]
    memory = stats["map"]["map_bytes"] if "map" in stats else stats["tsdf"]["mem_bytes"]
    print(f"| {name.replace('_', ' ')} m | {100 * total['within_ratio']:.2f} % "
          f"| {100 * total['median_abs_error_m']:.2f} cm | {100 * total['mean_abs_error_m']:.2f} cm "
          f"| {100 * total['hit_ratio']:.2f} % | {memory / 1e6:.1f} MB "
          f"| {stats['seconds']['total']:.1f} |")
EOF
