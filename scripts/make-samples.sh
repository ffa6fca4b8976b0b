#!/usr/bin/env bash
# Regenerates the OBJ meshes of the shipped samples in meshes/ with `goniospec generate`.
# Deterministic: the same binary writes the same files. Run from the repository root:
#   cargo build --release && scripts/make-samples.sh
set -euo pipefail
G=$(realpath "${GONIOSPEC:-${CARGO_TARGET_DIR:-target}/release/goniospec}")
cd meshes

# The seed's wavy soap film: 600 nm mean thickness, 8 nm RMS thickness variation,
# 60 nm RMS roughness (slopes of a few degrees), 2 um correlation length, on a 20 um tile.
for s in top bottom; do
  $G generate wavy-film --tile 20,20 --unit um -p surface=$s -p thickness=0.6 -p thickness_rms=0.008 \
    -p roughness_rms=0.06 -p correlation_length=2 -p resolution=64 -p seed=7 -p z=0 -o thin-film-600nm-$s.obj
done

# Rough gold: a GGX height field, alpha = 0.2, correlation length 2.5 um (tile / 8), on a
# 96 x 96 grid (two triangles a cell) over a 20 um tile.
$G generate microfacet --tile 20,20 --unit um -p distribution=ggx -p alpha=0.2 -p resolution=96 -p seed=3 -o rough-gold-ggx.obj

# Rough glass: Gaussian height field, 0.2 um RMS, 2 um correlation length.
$G generate gaussian --tile 20,20 --unit um -p rms=0.2 -p correlation_length=2 -p resolution=80 -p seed=5 -o rough-glass-gaussian.obj

# Aluminium V-grooves: 90 degree grooves, 10 per 20 um.
$G generate v-grooves --tile 20,20 --unit um -p angle_deg=90 -p count=10 -o v-grooves-90.obj

# Paint: no mesh. Its TiO2 pigment is far below the size where geometric optics holds and is
# a particle medium (Mie) in the binder (paint-pigments.toml).

# Pearlescent paint: TiO2-coated mica flakes (8 um, 0.4 um thick, 0.12 um coating, 8 degree tilt
# spread, 3 % by volume) in a 10 um binder layer, 40 um tile.
$G generate flakes --tile 40,40 --unit um -p size=8 -p thickness=0.4 -p coating=0.12 -p tilt_sd_deg=8 \
  -p volume_fraction=0.03 -p layer=[0.2,9.8] -p seed=13 -o pearl-flakes.obj
# The flakes are placed with room for the 0.12 um shell, but the sample applies the TiO2 layer
# as an exact coating on the mica faces: the shell mesh is not used.
rm -f pearl-flakes-coating.obj

# Metallic paint: aluminium flakes (10 um, 0.3 um thick, 6 degree tilt spread, 4 % by volume)
# in a 15 um binder layer, 40 um tile.
$G generate flakes --tile 40,40 --unit um -p size=10 -p thickness=0.3 -p tilt_sd_deg=6 \
  -p volume_fraction=0.04 -p layer=[0.5,14.5] -p seed=17 -o al-flakes.obj
