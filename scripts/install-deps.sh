#!/usr/bin/env bash
# Installs what goniospec needs from Debian's packages when it is missing:
# Embree (libembree-dev), libclang for bindgen, pkg-config, and for the batch tests GNU
# parallel and a single-node Slurm (slurmctld, slurmd, slurm-client, munge). Uses apt-get
# as root and sudo apt-get otherwise. Safe to run repeatedly; does nothing when all is present.
set -euo pipefail

pkgs=(libembree-dev libclang-dev pkg-config parallel slurmctld slurmd slurm-client munge)
missing=()
for p in "${pkgs[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  if ! command -v apt-get >/dev/null 2>&1; then
    echo "install-deps: apt-get not found; install Embree 3 or 4 headers, libclang and pkg-config by hand" >&2
    echo "install-deps: (or build without Embree: only the obvhs backend is then available)" >&2
    exit 0
  fi
  if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
  echo "install-deps: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

if ! command -v cargo >/dev/null 2>&1; then
  echo "install-deps: cargo not found. Install Rust 1.85 or newer with rustup (https://rustup.rs)." >&2
  exit 1
fi
