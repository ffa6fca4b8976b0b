#!/usr/bin/env bash
# The batch walk of issue 47, as a user types it: a library of three materials (the car
# paint, the metallic paint, and a bad one: a 20 um layer scattering 1e6 per um, which the
# simulation refuses), planned, run, checked, merged and reported. Each command's exit
# status and wall time follow its output. Expected: run, status, merge and report exit 1
# naming the bad material; the page is written with both paints and a marked row.
#
#   scripts/batch-walk.sh [FOLDER]     # default: a temporary folder, kept and printed
set -u
cd "$(dirname "$0")/.."
R=$PWD
G=$(realpath "${GONIOSPEC:-${CARGO_TARGET_DIR:-target}/release/goniospec}")
W=${1:-$(mktemp -d)}
mkdir -p "$W" && cd "$W" || exit 1
rm -rf lib
cat > dense.toml <<'T'
[sample]
name = "dense white"
unit = "um"
tile = [5.0, 5.0]
[media.air]
n = 1.0
[media.paint]
n = 1.49
henyey_greenstein = { g = 0.6, scattering_per_um = 1e6, absorption_per_um = 0.01 }
[stack]
ambient = "air"
layers = [{ medium = "paint", thickness = 20.0 }]
substrate = "air"
T
cat > plan.toml <<T
[defaults]
theta_i = [0, 30, 60]
wavelengths = "380:780:10"
rays = 512
representations = ["table"]

[[material]]
sample = "$R/meshes/car-paint.toml"
name = "carpaint"

[[material]]
sample = "$R/meshes/metallic-paint.toml"
name = "metallic"

[[material]]
sample = "dense.toml"
name = "dense"
T
t(){ local s; s=$(date +%s.%N); "$@"; local rc=$?
  printf '[exit %d, %.1f s: goniospec %s]\n' "$rc" "$(echo "$(date +%s.%N) - $s" | bc)" "${*:2}"; }
t "$G" batch plan plan.toml -o lib
t "$G" batch run lib
t "$G" batch status lib
t "$G" batch merge lib
t "$G" batch report lib
echo "the library: $W/lib (page: $W/lib/report/index.html)"
