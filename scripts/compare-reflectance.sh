#!/usr/bin/env bash
# Refactoring check: two goniospec builds must print the same `reflectance` CSV, to the
# last digit, for every shipped sample.
#
#   scripts/compare-reflectance.sh OLD_BINARY NEW_BINARY [RAYS] [SAMPLE.toml...]
#
# Simulates each sample (default: every meshes/*.toml) at 0, 30 and 60 degrees,
# 400..700 nm in 50 nm bins, with the power cutoff the multiply scattering samples need
# (1e-4), with both binaries (same seed), and compares the CSV of every angle. Exits 1 on
# a difference or when a run fails.
set -euo pipefail
cd "$(dirname "$0")/.."
old=$(realpath "$1")
new=$(realpath "$2")
rays=${3:-1000}
shift 3 || shift $#
samples=("$@")
[ ${#samples[@]} -gt 0 ] || samples=(meshes/*.toml)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
status=0
for s in "${samples[@]}"; do
  name=$(basename "$s" .toml)
  for which in old new; do
    bin=${!which}
    if ! "$bin" simulate "$s" --theta-i 0,30,60 --rays "$rays" --wavelengths 400:700:50 \
      --cutoff 1e-4 -o "$work/$name-$which.gsa" > "$work/log" 2>&1; then
      echo "FAILED: $which $s"
      tail -3 "$work/log"
      exit 1
    fi
    for t in 0 30 60; do
      "$bin" reflectance "$work/$name-$which.gsa" --theta-i "$t" > "$work/$name-$which-$t.csv"
    done
  done
  for t in 0 30 60; do
    if cmp -s "$work/$name-old-$t.csv" "$work/$name-new-$t.csv"; then
      echo "same: $name theta_i $t"
    else
      echo "DIFFERENT: $name theta_i $t"
      diff "$work/$name-old-$t.csv" "$work/$name-new-$t.csv" | head -14 || true
      status=1
    fi
  done
done
exit $status
