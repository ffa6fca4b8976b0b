#!/usr/bin/env bash
# The batch report of a small library (three shipped samples) opened in a real headless
# browser: Debian's chromium driven by Selenium through chromium-driver (installed when
# missing), the page's HTML through a strict HTML5 parser, and its colours against the PyPI
# colour-science package (.venv-report). Writes the library to OUT/lib and a screenshot to
# OUT/report.png; prints `name: value unit` figures.
#
#   scripts/report-browser.sh [GONIOSPEC_BINARY] [OUT] [PLAN.toml]
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-${CARGO_TARGET_DIR:-target}/release/goniospec}")
out=$(realpath -m "${2:-out/report-browser}")
plan=${3:-}
venv=${REPORT_VENV:-.venv-report}
scripts/venvs.sh report
rm -rf "$out/lib"
mkdir -p "$out/lib"
if [ -z "$plan" ]; then
  plan=$out/lib/plan.toml
  cat > "$plan" <<PLAN
[defaults]
theta_i = [0, 30, 60]
wavelengths = "400:700:20"
rays = 256
representations = ["table"]

[[material]]
sample = "$PWD/meshes/rough-gold.toml"
name = "rough-gold"

[[material]]
sample = "$PWD/meshes/thin-film-600nm.toml"
name = "wavy-soap-film"

[[material]]
sample = "$PWD/meshes/ar-coating.toml"
name = "ar-coating"
representations = ["kdtree"]
PLAN
fi
"$bin" batch plan "$plan" -o "$out/lib"
"$bin" batch run "$out/lib"
"$bin" batch merge "$out/lib"
"$bin" batch report "$out/lib"
"$venv/bin/python" scripts/report-browser.py "$bin" "$out/lib" "$out"
