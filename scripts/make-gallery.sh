#!/usr/bin/env bash
# Renders every shipped sample as a sphere into docs/gallery/ (small PNGs linked from the
# README). Run from the repository root after `cargo build --release`.
set -euo pipefail
G=$(realpath "${GONIOSPEC:-${CARGO_TARGET_DIR:-target}/release/goniospec}")
OUT=docs/gallery
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
mkdir -p "$OUT"
ANGLES=0,5,10,15,20,25,30,35,40,45,50,55,60,65,70,75,80,85
render() { # name rays extra-simulate-options...
  local name=$1 rays=$2
  shift 2
  echo "== $name"
  $G simulate "meshes/$name.toml" --theta-i $ANGLES --rays "$rays" --wavelengths 380:780:20 "$@" -o "$TMP/$name.gsa" 2>&1 | tail -1
  $G build "$TMP/$name.gsa" --repr table -o "$TMP/$name.gsb" > /dev/null
  $G render "$TMP/$name.gsb" -o "$TMP/$name.exr" --width 192 --height 192 --spp 8 --env constant --light dir:50,-120 > /dev/null
  cp "$TMP/$name.png" "$OUT/$name.png"
}
render thin-film-600nm 2048
render flat-soap-film 64
render soap-film-dispersive 64
render ar-coating 64
render oil-slick 64
render rough-gold 1024
render rough-glass 1024
render v-grooves-aluminium 512
render paint-pigments 4096
render pearlescent-paint 1024
render metallic-paint 1024
# A grating is anisotropic: lit from every 30 degrees of azimuth (under the default auto
# every cell takes the rigorous solver, the C-method in conical incidence off the grooves'
# plane), built as an anisotropic kd-tree, whose x axis runs around the sphere.
render_grating() { # name rays
  local name=$1 rays=$2
  echo "== $name"
  $G simulate "meshes/$name.toml" --theta-i 0,10,20,30,40,50,60,70,80 --phi-i 0,30,60,90,120,150,180,210,240,270,300,330 --rays "$rays" --wavelengths 380:780:20 -o "$TMP/$name.gsa" 2>&1 | grep -E "^methods" || true
  $G build "$TMP/$name.gsa" -o "$TMP/$name.gsb" > /dev/null
  $G render "$TMP/$name.gsb" -o "$TMP/$name.exr" --width 192 --height 192 --spp 8 --env constant --light dir:50,-120 > /dev/null
  cp "$TMP/$name.png" "$OUT/$name.png"
}
render_grating holographic-foil 512
render_grating optical-disc-track 512
ls -la "$OUT"
