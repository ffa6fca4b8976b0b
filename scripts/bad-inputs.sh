#!/usr/bin/env bash
# A pass of bad inputs, as a careless or hostile user sends them (issue 12): NaN, infinite
# and huge numbers in every numeric flag and generator key, sizes that cannot fit,
# truncated and bit-flipped .gsa/.gsb files, malformed OBJ meshes and sample files,
# devices and directories as inputs. Reports every panic (101), abort (134) or other
# signal, and every NaN printed with exit status 0; runs still going after 30 s (a huge
# but legal amount of work) are listed apart.
#
#   scripts/bad-inputs.sh            # prints "N runs, B bad, S still running after 30 s"
#
# Exits 1 when anything was bad.
set -u
cd "$(dirname "$0")/.."
G=$(realpath "${GONIOSPEC:-${CARGO_TARGET_DIR:-target}/release/goniospec}")
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
cd "$W"
cat > v.toml <<'T'
[sample]
name = "glass sheet"
unit = "um"
tile = [20, 20]
[media.air]
n = 1.0
[media.glass]
n = 1.5
[stack]
mode = "mesh"
ambient = "air"
layers = [{ medium = "glass", thickness = 1.0 }]
substrate = "air"
T
printf '\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > bom.obj
printf 'v 0 0 0 # c\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > cmt.obj
printf 'v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r' > cr.obj
printf 'v x y z 0\n' > w0.obj
printf 'v 0 0 0\nv 4 0 0\nv 4 4 0\nv 2 1 0\nv 0 4 0\nf 1 2 3 4 5\n' > concave.obj
bad=0; n=0
slow=0
run(){ n=$((n+1)); timeout 30 "$@" > o.txt 2> e.txt; rc=$?
  if [ $rc -eq 124 ]; then echo "still running after 30 s: $*"; slow=$((slow+1)); return; fi
  if [ $rc -ge 100 ] || grep -q "panicked" e.txt || { [ $rc -eq 0 ] && grep -qi "nan" o.txt; }; then
    echo "BAD rc=$rc: $*"; head -c 300 e.txt; echo; bad=$((bad+1)); fi; }
$G simulate v.toml --theta-i 0 --rays 200 --wavelengths 500 --monochromatic -o good.gsa >/dev/null 2>&1
$G build good.gsa -o good.gsb >/dev/null 2>&1
for v in nan inf -inf 1e309 -0 1e-320; do
  run $G simulate v.toml --theta-i 30 --phi-i $v --rays 10 -o x.gsa
  run $G simulate v.toml --theta-i $v --rays 10 -o x.gsa
  run $G simulate v.toml --cutoff $v --rays 10 -o x.gsa
  run $G simulate v.toml --coherence-radius-nm $v --rays 10 -o x.gsa
  run $G simulate v.toml --tolerance $v --rays 10 -o x.gsa
  run $G eval good.gsb --theta-i 30 --theta-o $v --phi-i 0
  run $G eval good.gsb --theta-i $v --theta-o 30
  run $G render good.gsb --light dir:$v,0 -o x.exr --width 8 --height 8
  run $G render good.gsb --fov $v -o x.exr --width 8 --height 8
  run $G render good.gsb --camera $v,0,3 -o x.exr --width 8 --height 8
  run $G render good.gsb --light-strength $v -o x.exr --width 8 --height 8
  run $G analytic v.toml --theta-i $v --wavelengths 500 --monochromatic
  run $G reflectance good.gsa --theta-i $v
  run $G generate flat -p z=$v -o x.obj --force
  run $G generate gaussian -p rms=$v -p correlation_length=2 -p resolution=32 -o x.obj --force
  run $G generate cosine -p amplitude=$v -p resolution=8 -o x.obj --force
  run $G generate wedge -p slope_deg=$v -o x.obj --force
  run $G generate v-grooves -p angle_deg=$v -p count=3 -o x.obj --force
  run $G generate microfacet -p distribution=\"ggx\" -p alpha=$v -p resolution=32 -o x.obj --force
  run $G generate pigment-spheres -p radius=$v -p volume_fraction=0.1 -p 'layer=[0,5]' -o x.obj --force
  run $G generate flakes -p size=$v -p thickness=0.1 -p tilt_sd_deg=5 -p volume_fraction=0.1 -p 'layer=[0,5]' -o x.obj --force
  run $G generate flakes -p size=1 -p thickness=0.1 -p tilt_sd_deg=$v -p volume_fraction=0.1 -p 'layer=[0,5]' -o x.obj --force
  run $G generate wavy-film -p surface=\"top\" -p thickness=$v -p thickness_rms=0.01 -p roughness_rms=0.05 -p correlation_length=2 -p resolution=32 -o x.obj --force
  run $G generate flat --tile $v,20 -o x.obj --force
  for key in "n = 1.5" "thickness = 1.0"; do
    k=${key%% =*}
    sed "s/$key/$k = $v/" v.toml > w.toml; run $G check w.toml; run $G simulate w.toml --rays 10 -o x.gsa
  done
  sed "s/n = 1.5/n = 1.5\nk = $v/" v.toml > w.toml; run $G simulate w.toml --rays 10 -o x.gsa
  sed "s/tile = \[20, 20\]/tile = [$v, 20]/" v.toml > w.toml; run $G check w.toml
done
for big in 0 1 65536 4294967296 18446744073709551615; do
  run $G simulate v.toml --rays $big -o x.gsa
  run $G simulate v.toml --rays 10 --theta-o-bins $big -o x.gsa
  run $G simulate v.toml --rays 10 --threads $big -o x.gsa
  run $G simulate v.toml --rays 10 --max-depth $big -o x.gsa
  run $G simulate v.toml --rays 10 --max-rays $big --tolerance 0.1 -o x.gsa
  run $G render good.gsb --width $big --height 8 -o x.exr
  run $G render good.gsb --spp $big --width 8 --height 8 -o x.exr
  run $G generate gaussian -p rms=0.1 -p correlation_length=2 -p resolution=$big -o x.obj --force
  run $G generate v-grooves -p angle_deg=90 -p count=$big -o x.obj --force
  run $G generate pigment-spheres -p radius=1 -p volume_fraction=0.1 -p 'layer=[0,5]' -p subdivisions=$big -o x.obj --force
  run $G build good.gsa --repr kdtree --k $big -o x.gsb
  run $G bench eval --buckets $big
done
for w in "380:780:0" "380:780:-1" "780:380:10" "1:1e300:1" "0,1" "a,b" ":" "" "380:780:0.001" "nan:780:1"; do
  run $G simulate v.toml --rays 10 --wavelengths "$w" -o x.gsa
done
for l in "dir:" "dir:1" "dir:1,2,3" "point:a,b,c" "x" "point:1e308,1e308,1e308"; do run $G render good.gsb --light "$l" -o x.exr --width 8 --height 8; done
# Files
for f in good.gsa good.gsb; do
  for cut in 0 5 16 30 100; do head -c $cut $f > t.bin; run $G info t.bin; run $G build t.bin -o x.gsb; run $G eval t.bin --theta-i 10 --theta-o 10; done
  for i in $(seq 1 40); do python3 -c "
import random,sys
b=bytearray(open('$f','rb').read()); random.seed($i)
for _ in range(3): b[random.randrange(len(b))]^=1<<random.randrange(8)
open('t.bin','wb').write(b)"; run $G info t.bin; run $G build t.bin -o x.gsb; run $G eval t.bin --theta-i 10 --theta-o 10; run $G render t.bin -o x.exr --width 4 --height 4; done
done
: > empty.obj; printf 'v 1e39 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n' > huge.obj; printf 'f 1 2 3\n' > noverts.obj; head -c 2000 /dev/urandom > rand.obj
for m in empty huge noverts rand bom cmt cr w0 concave; do sed "s/MESH/$m.obj/" > mm.toml <<'T'
[sample]
name = "m"
unit = "um"
tile = [4, 4]
[media.air]
n = 1.0
[media.glass]
n = 1.5
[[interface]]
mesh = "MESH"
front = "air"
back = "glass"
T
run $G check mm.toml; run $G simulate mm.toml --rays 10 -o x.gsa; done
run $G check /dev/null; run $G check /nonexistent.toml; run $G check /tmp; run $G simulate /dev/urandom -o x.gsa
run $G study /dev/null -o st; run $G merge good.gsa good.gsa -o m.gsa
echo "$n runs, $bad bad, $slow still running after 30 s"
[ "$bad" -eq 0 ]
