#!/usr/bin/env bash
# Packs the Blender add-on (blender_addon/shinevdb/) into an installable zip:
#   scripts/build_blender_addon.sh [OUTPUT_ZIP]     (default: build/shinevdb_blender_addon.zip)
# Install it in Blender with Edit › Preferences › Add-ons › Install… and enable "ShineVDB".
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
output="$(realpath -m "${1:-$root/build/shinevdb_blender_addon.zip}")"
mkdir -p "$(dirname "$output")"
tmp="$output.tmp.$$"
trap 'rm -f "$tmp"' EXIT
cd "$root/blender_addon"
# The zip holds the package folder itself, as Blender's installer expects; no byte code.
find shinevdb -type f -name '*.py' -not -path '*/__pycache__/*' | LC_ALL=C sort \
    | xargs cmake -E tar cf "$tmp" --format=zip
mv "$tmp" "$output"
echo "wrote $output"
