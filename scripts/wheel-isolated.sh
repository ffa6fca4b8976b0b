#!/usr/bin/env bash
# Proves the repaired wheel is self-contained: inside a private mount namespace, every
# Embree and TBB shared library of the system is hidden under an empty file, a fresh virtual
# environment installs the wheel (and numpy and the PyPI tmm package), and then
#   - the hiding holds (loading the system's libembree3 by name fails),
#   - `import goniospec` works and `backends()` lists Embree with its version,
#   - the Embree the process mapped is the one inside the wheel (goniospec.libs/),
#   - the flat soap film simulated with Embree equals the tmm package within 1e-6.
# Prints `name: value unit` figures. Needs root for `unshare -m` and bind mounts; says so
# and exits 0 otherwise.
#
#   scripts/wheel-isolated.sh [WHEEL]      (default: the one scripts/python.sh built)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
wheel=$(realpath "${1:-$(ls python/dist/goniospec-*.whl | head -1)}")
if [ "$(id -u)" != 0 ]; then
  echo "wheel-isolated: skipped, hiding the system's libraries needs root (unshare -m)"
  exit 0
fi
if ! command -v unshare >/dev/null; then
  echo "wheel-isolated: unshare (util-linux) is missing" >&2
  exit 1
fi
if ! unshare -m true 2>/dev/null; then
  echo "wheel-isolated: skipped, this machine refuses a private mount namespace (unshare -m: no CAP_SYS_ADMIN in this container)"
  exit 0
fi
# Every file behind the names the dynamic loader knows for Embree and TBB.
mapfile -t libs < <(ldconfig -p | awk '/lib(embree|tbb)[^ ]*\.so/ {print $NF}' | xargs -r realpath | sort -u)
if [ ${#libs[@]} -eq 0 ]; then
  echo "wheel-isolated: no system Embree or TBB to hide; the check still runs"
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
: > "$work/empty"
cat > "$work/check.py" <<'EOF'
import ctypes, os, sys, time
import numpy as np

t0 = time.monotonic()
import goniospec as gs
print(f"import_s: {time.monotonic() - t0:.3f} s")
try:
    ctypes.CDLL("libembree3.so.3")
    hidden = False
except OSError:
    hidden = True
if not hidden and sys.argv[1] == "1":
    sys.exit("the system's libembree3 still loads: the namespace hides nothing")
b = {x["name"]: x for x in gs.backends()}
if not b.get("embree", {}).get("available"):
    sys.exit(f"Embree is not available from the wheel: {b.get('embree')}")
print(f"embree_version: {b['embree']['version']}")
maps = open("/proc/self/maps").read().split("\n")
embree = {l.split()[-1] for l in maps if "libembree" in l}
if not embree or not all("/goniospec.libs/" in p for p in embree):
    sys.exit(f"the process mapped Embree from {embree}, not from the wheel")
print(f"embree_mapped_from_wheel: 1 bool")

import tmm
s = gs.Sample.load(os.path.join(sys.argv[2], "meshes", "flat-soap-film.toml"))
t0 = time.monotonic()
acc = gs.simulate(s, theta_i_deg=[30], wavelengths="450,550,650", monochromatic=True, rays=64,
                  coherence_radius_nm=float("inf"), backend="embree", progress=False)
print(f"simulate_s: {time.monotonic() - t0:.3f} s")
r = acc.reflectance(30)
worst = 0.0
for lam, got in zip(r["lambda_nm"], r["R"]):
    # meshes/flat-soap-film.toml: 600 nm of index 1.33 between air; unpolarised R.
    th = np.radians(30.0)
    want = 0.5 * sum(tmm.coh_tmm(p, [1.0, 1.33, 1.0], [np.inf, 600.0, np.inf], th, lam)["R"]
                     for p in "sp")
    worst = max(worst, abs(got - want))
print(f"soap_film_max_abs_error_vs_tmm: {worst:.2e} 1")
if worst > 1e-6:
    sys.exit(f"the soap film differs from tmm by {worst} (> 1e-6)")
print("wheel-isolated: ok")
EOF
wheel_bytes=$(stat -c %s "$wheel")
echo "wheel: $(basename "$wheel")"
echo "wheel_bytes: $wheel_bytes bytes"
python3 -c 'import sys, zipfile
for i in zipfile.ZipFile(sys.argv[1]).infolist():
    if "goniospec.libs/" in i.filename:
        print(f"bundled: {i.filename} {i.file_size} bytes")' "$wheel"
export WORK=$work ROOT=$root WHEEL=$wheel
unshare -m bash -euo pipefail -c '
  mount --make-rprivate /
  for lib in "$@"; do mount --bind "$WORK/empty" "$lib"; done
  echo "hidden: $# system libraries"
  python3 -m venv "$WORK/venv"
  t0=$(date +%s%N)
  "$WORK/venv/bin/pip" install --quiet --disable-pip-version-check "$WHEEL" tmm
  echo "install_ms: $(( ($(date +%s%N) - t0) / 1000000 )) ms"
  cd "$WORK" && "$WORK/venv/bin/python" "$WORK/check.py" "$(( $# > 0 ))" "$ROOT"
' hide "${libs[@]}"
