#!/usr/bin/env bash
# Fuzz every parser with AFL++ through afl.rs (stable Rust), one after the other.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
#
# Seeds come from fuzz/corpus/TARGET (the shipped samples, tables, studies and small
# .gsa/.gsb files); findings go to ${FUZZ_OUT:-out/fuzz}/TARGET. Prints one line per
# target (executions, coverage, crashes, hangs) and writes them to SUMMARY.txt there.
# Exits 1 when any target crashed: copy the input into fuzz/regressions/TARGET/ and fix.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-600}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=(obj sample media-table media-model gsa gsb bsdf study cli-values x3p gsf npy exr png tiff ply stl mesh-cache batch-plan batch-manifest)
fi
out=${FUZZ_OUT:-out/fuzz}
./scripts/install-deps.sh
if ! command -v cargo-afl >/dev/null 2>&1; then
  echo "installing cargo-afl (afl.rs; builds AFL++ once)"
  cargo install cargo-afl --locked --version 0.18.2
fi
# AFL++ itself, built once per Rust version into ~/.local/share/afl.rs.
config_log=$(mktemp)
if ! cargo afl config --build > "$config_log" 2>&1; then
  grep -q "already built" "$config_log" || {
    echo "cargo afl config --build failed:"
    cat "$config_log"
    rm -f "$config_log"
    exit 1
  }
fi
rm -f "$config_log"
target_dir=${CARGO_TARGET_DIR:-$PWD/fuzz/target}/afl
(cd fuzz && cargo afl build --release --target-dir "$target_dir")
bin=$target_dir/release/goniospec-fuzz
# No CPU pinning: CI containers and busy machines may have no free core to bind.
export AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 AFL_NO_UI=1 AFL_NO_AFFINITY=1
mkdir -p "$out"
summary=$out/SUMMARY.txt
: > "$summary"
status=0
for t in "${targets[@]}"; do
  rm -rf "${out:?}/$t"
  # -t: a 5 s time-out per input (generators legitimately take seconds); -V: run time.
  cargo afl fuzz -i "fuzz/corpus/$t" -o "$out/$t" -V "$secs" -t 5000 "$bin" "$t" \
    > "$out/$t.log" 2>&1 || { echo "afl-fuzz failed for $t: see $out/$t.log"; status=1; continue; }
  s=$out/$t/default/fuzzer_stats
  get() { awk -F' *: *' -v k="$1" '$1 == k { print $2 }' "$s"; }
  line="$t: execs $(get execs_done), $(get execs_per_sec) exec/s, edges $(get edges_found), map coverage $(get bitmap_cvg), corpus $(get corpus_count), crashes $(get saved_crashes), hangs $(get saved_hangs), ${secs} s"
  echo "$line" | tee -a "$summary"
  if [ "$(get saved_crashes)" != "0" ]; then
    status=1
  fi
done
exit $status
