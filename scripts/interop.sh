#!/usr/bin/env bash
# Interop with the renderers people use: exports RGL .bsdf files and checks them with an
# independent reader and with Mitsuba 3 (tests/interop/rgl_mitsuba.py); the measured RGL
# files read by Mitsuba 3 against goniospec's reader, and `compare`'s colours and CIEDE2000
# against colour-science (tests/interop/measured_mitsuba.py); Mueller-matrix
# BRDFs as Mitsuba's measured_polarized files, against its own conductor and rendered with
# its Stokes integrator (tests/interop/mueller_mitsuba.py); and the Mie series
# against the PyPI miepython package (tests/interop/mie_miepython.py), and volume scattering
# against iadpython's adding-doubling (tests/interop/rt_iadpython.py); and the diffraction
# method against RCWA (PyPI meent: tests/interop/grating_meent.py writes the orders, the
# `against_rcwa` test of tests/diffraction.rs compares); and gold gratings against the
# Rayleigh-Fourier method, checked against PyPI grcwa (tests/interop/grating_rayleigh.py;
# the `metal_*` tests of tests/diffraction.rs compare the diffraction method's orders and
# the rays' R, or the warning on R); and gold V-grooves against RCWA for TE (grcwa:
# tests/interop/vgroove_rcwa.py; `gold_v_grooves_against_rigorous_te_or_warn` in
# tests/tilted_absorbers.rs compares the rays' TE R, or the warning), and the local
# transfer-matrix film that test file uses for tilted gold films, against RCWA for TE
# (tests/interop/roof_rcwa.py); and the rigorous solver against independent Fourier modal
# methods on the same staircases (meent for glass sinusoids, nannos with Li's rule for gold
# and crossed gratings: tests/interop/rcwa_nannos.py; `against_references` in
# tests/rcwa.rs compares), and the C-method on gold sinusoids in TE and TM against the same
# Rayleigh-Fourier references (`gold_sinusoids_in_tm_against_rayleigh_fourier` in
# tests/cmethod.rs). Not run here: the many-particle T-matrix reference for
# dependent scattering (tests/interop/tmatrix_smuthi.py; SMUTHI needs gfortran and an older
# NumPy), whose stored result tests/particle_media.rs reads; and rough gold's Mueller
# matrices against NIST SCATMECH's facet model (tests/interop/mueller_scatmech.py; PyPI
# pyscatmech builds from C++ in minutes), and the rigorous solver against SCATMECH's RCW
# models (tests/interop/rcw_scatmech.py, whose stored output tests/rcwa_scatmech.rs reads).
#
#   scripts/interop.sh [GONIOSPEC_BINARY]
#
# Makes a project-local virtual environment (.venv-interop) with numpy and Mitsuba 3 from
# PyPI when it is missing; set INTEROP_VENV to use another one.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-${CARGO_TARGET_DIR:-target}/release/goniospec}")
venv=${INTEROP_VENV:-.venv-interop}
t_venv=$SECONDS
scripts/venvs.sh interop
echo "interop_seconds: venv: $((SECONDS - t_venv)) s"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# Each step's wall time and the processor time it took (user and system, all its
# processes), for keeping CI within its budget (issue 75): "interop_seconds: NAME: S s"
# and "interop_cpu_seconds: NAME: C s" after each.
timed() {
  local t0=$SECONDS name=$1 cpu
  shift
  cpu=$(mktemp)
  /usr/bin/time -f "%U %S" -o "$cpu" "$@"
  echo "interop_seconds: $name: $((SECONDS - t0)) s"
  awk -v n="$name" '{ printf "interop_cpu_seconds: %s: %.0f s\n", n, $1 + $2 }' "$cpu"
  rm -f "$cpu"
}
timed rgl_mitsuba "$venv/bin/python" tests/interop/rgl_mitsuba.py "$bin" "$work"
timed measured_mitsuba "$venv/bin/python" tests/interop/measured_mitsuba.py "$bin" "$work/measured"
timed mueller_mitsuba "$venv/bin/python" tests/interop/mueller_mitsuba.py "$bin" "$work/mueller"
timed mie_miepython "$venv/bin/python" tests/interop/mie_miepython.py "$bin"
timed rt_iadpython "$venv/bin/python" tests/interop/rt_iadpython.py "$bin" "$work/rt"
# The rigorous references take no input from goniospec: each is a pure function of its
# script (and pinned packages), so its JSON is kept in tests/reference/interop/ beside the
# SHA-256 of the script that made it, and made again here only when the script differs
# (or INTEROP_REFRESH=1): the comparisons below always use what this commit's scripts
# compute, for 170 s less of CI (issue 75). Commit the files a refresh rewrites.
refs=tests/reference/interop
reference() {
  local name=$1 script=$2 sum
  sum=$(sha256sum "$script" | cut -d' ' -f1)
  if [ "${INTEROP_REFRESH:-0}" != 1 ] && [ -f "$refs/$name.json" ] \
    && [ "$(cat "$refs/$name.json.script-sha256" 2>/dev/null)" = "$sum" ]; then
    echo "interop: $refs/$name.json, made by $script as it is in this commit"
  else
    echo "interop: making $refs/$name.json ($script changed or INTEROP_REFRESH=1)"
    timed "$name" "$venv/bin/python" "$script" "$refs/$name.json.tmp"
    mv "$refs/$name.json.tmp" "$refs/$name.json"
    echo "$sum" > "$refs/$name.json.script-sha256"
  fi
}
reference grating-meent tests/interop/grating_meent.py
reference grating-rayleigh tests/interop/grating_rayleigh.py
reference vgroove-rcwa tests/interop/vgroove_rcwa.py
reference rcwa-nannos tests/interop/rcwa_nannos.py
timed roof_rcwa "$venv/bin/python" tests/interop/roof_rcwa.py
timed "diffraction against_rcwa" env GONIOSPEC_RCWA_JSON="$refs/grating-meent.json" cargo test --release --test diffraction against_rcwa -- --ignored --nocapture
timed "diffraction metal_" env GONIOSPEC_METAL_GRATING_JSON="$refs/grating-rayleigh.json" cargo test --release --test diffraction metal_ -- --ignored --nocapture
timed "tilted_absorbers gold_v_grooves_against_rigorous" env GONIOSPEC_VGROOVE_JSON="$refs/vgroove-rcwa.json" cargo test --release --test tilted_absorbers gold_v_grooves_against_rigorous -- --ignored --nocapture
timed "rcwa against_references" env GONIOSPEC_RCWA_REFS_JSON="$refs/rcwa-nannos.json" cargo test --release --test rcwa against_references -- --ignored --nocapture
timed "rcwa gold_sinusoids_against_rayleigh_fourier" env GONIOSPEC_METAL_GRATING_JSON="$refs/grating-rayleigh.json" cargo test --release --test rcwa gold_sinusoids_against_rayleigh_fourier -- --ignored --nocapture
timed "cmethod gold_sinusoids_in_tm_against_rayleigh_fourier" env GONIOSPEC_METAL_GRATING_JSON="$refs/grating-rayleigh.json" cargo test --release --test cmethod gold_sinusoids_in_tm_against_rayleigh_fourier -- --ignored --nocapture
# The peer benchmark (issue 31): Mitsuba 3 and goniospec on the same mesh and rays must hit
# the same triangle, ray by ray (all but 1e-4: edge ties); its speed figures are printed,
# speed is not asserted here. Mitsuba's llvm_ad_rgb variant loads the system's LLVM, version 15 or newer (Debian 12: libllvm15;
# the libllvm14 that libclang-dev brings is too old for Dr.Jit).
llvm_ok=0
for f in /usr/lib/x86_64-linux-gnu/libLLVM-*.so.*; do
  v=${f##*/libLLVM-}
  v=${v%%.*}
  if [[ $v =~ ^[0-9]+$ ]] && ((v >= 15)); then llvm_ok=1; fi
done
if ((!llvm_ok)); then
  if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
  echo "== installing libllvm15 for Mitsuba's LLVM variant"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm15 >/dev/null
fi
t_peer=$SECONDS
"$bin" bench peer --rays 200000 --trees 2000 --python "$venv/bin/python" | tee "$work/peer.txt"
echo "interop_seconds: bench peer: $((SECONDS - t_peer)) s"
awk '/^same_triangle_fraction:/ { ok = ($2 >= 0.9999) } END { exit !ok }' "$work/peer.txt" \
  || { echo "bench peer: Mitsuba and goniospec hit different triangles on more than 1e-4 of the rays"; exit 1; }
