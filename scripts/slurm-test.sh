#!/usr/bin/env bash
# The batch test on a real Slurm: starts a single-node cluster (scripts/slurm-local.sh),
# submits a plan as job arrays of 2 and 5 shards (2 tasks at a time) with the merge chained by
# --dependency=afterok, waits for it, and checks the merged files byte for byte against
# the same plan run in one process. Stops the cluster it started, even on failure.
#
#   scripts/slurm-test.sh [GONIOSPEC_BINARY]
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-${CARGO_TARGET_DIR:-target}/release/goniospec}")
if [ "$(id -u)" != 0 ]; then
  echo "slurm-test: NOT RUN: the local Slurm cluster needs root (CI runs it as root)" >&2
  exit 0
fi
work=$(mktemp -d)
export SLURM_LOCAL_DIR=$work/slurm
cleanup() { scripts/slurm-local.sh stop >/dev/null 2>&1 || true; rm -rf "$work"; }
trap cleanup EXIT
eval "export $(scripts/slurm-local.sh start)"

root=$PWD
cat > "$work/plan.toml" <<PLAN
[defaults]
theta_i = [0, 20, 40, 60]
wavelengths = "400:700:50"
rays = 512
representations = ["table", "kdtree"]

[[material]]
sample = "$root/meshes/rough-gold.toml"
name = "gold"

[[material]]
sample = "$root/meshes/thin-film-600nm.toml"
theta_i = [10, 30]
PLAN
"$bin" batch plan "$work/plan.toml" -o "$work/one" >/dev/null
"$bin" batch run "$work/one" >/dev/null
"$bin" batch merge "$work/one" >/dev/null
status=0
for shards in 2 5; do
  lib=$work/lib$shards
  "$bin" batch plan "$work/plan.toml" -o "$lib" >/dev/null
  "$bin" batch slurm "$lib" --shards $shards --limit 2 >/dev/null
  (
    cd "$lib"
    mkdir -p logs
    start=$(date +%s.%N)
    jid=$(sbatch --parsable units.sbatch)
    sbatch --wait --parsable --dependency=afterok:"${jid%%;*}" merge.sbatch >/dev/null
    end=$(date +%s.%N)
    echo "slurm_${shards}_shards_wall_s: $(awk "BEGIN { printf \"%.1f\", $end - $start }")"
  )
  for f in gold.gsa gold-table.gsb gold-kdtree.gsb thin-film-600nm.gsa thin-film-600nm-table.gsb thin-film-600nm-kdtree.gsb; do
    if ! cmp -s "$work/one/out/$f" "$lib/out/$f"; then
      echo "slurm-test: DIFFERENT with $shards shards: $f" >&2
      status=1
    fi
  done
  tasks=$(ls "$lib/logs" | grep -c '^units-' || true)
  if [ "$tasks" != $shards ]; then
    echo "slurm-test: $tasks array tasks ran, expected $shards" >&2
    status=1
  fi
done
if [ $status = 0 ]; then
  echo "slurm-test: arrays of 2 and 5 shards merge to the same bytes as one process (6 files each)"
else
  echo "slurm-test: FAILED" >&2
  exit 1
fi
