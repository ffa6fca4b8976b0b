#!/usr/bin/env bash
# Makes the shipped materials (materials/*.toml) from the measurements in data/measured/:
# each a `goniospec match` of its starting recipe (materials/templates/) to the RGL
# measurement it is named after, the fitted recipe copied into materials/ and the whole
# match (trace, comparison, records) kept in out/match/NAME. A rerun resumes from the
# records. The templates name no files, so each fitted.toml reads the same wherever it
# lies. Usage: scripts/match-materials.sh [wrap-film|white-paper ...]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release/goniospec}
OUT=${OUT:-out/match}
[ -x "$BIN" ] || cargo build --release
mkdir -p "$OUT"

match() {
    local name=$1
    shift
    "$BIN" match "materials/templates/$name.toml" "$@" -o "$OUT/$name"
    cp "$OUT/$name/fitted.toml" "materials/$name.toml"
    echo "match-materials: materials/$name.toml from $OUT/$name"
}

for name in "${@:-wrap-film white-paper}"; do
    for n in $name; do
        case $n in
        wrap-film)
            # The colour-change wrap film: four parameters from the template's start (24
            # Halton starts found a film of the second order, 0.67 um, and a worse error:
            # 10.9 against 10.7).
            match wrap-film --measured data/measured/cc_ibiza_sunset_rgb.bsdf \
                --vary interface.0.generator.alpha=0.03:0.4:log \
                --vary interface.0.coating.0.thickness=0.1:1.2 \
                --vary media.film.n=1.4:2.6 \
                --vary media.vinyl.k=0.01:2:log \
                --max-evaluations 120 --final-rays 16384
            ;;
        white-paper)
            # White paper: the scatterers' amount and size; six wavelength bins (the
            # measurement is RGB) and 1,024 trees a candidate, as a particle medium's
            # trees cost some 5 ms each.
            match white-paper --measured data/measured/paper_white_rgb.bsdf \
                --vary media.sheet.particles.volume_fraction=0.05:0.5:log \
                --vary media.sheet.particles.log_normal.median_radius_nm=200:2000:log \
                --rays 1024 --final-rays 2048 --wavelengths 400:700:50 --max-evaluations 30
            ;;
        *)
            echo "match-materials: no material '$n' (wrap-film, white-paper)" >&2
            exit 2
            ;;
        esac
    done
done
