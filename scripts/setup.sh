#!/usr/bin/env bash
# Set up OutCast on a fresh machine: system libraries Qt needs, then the package with the
# training/test extras (torch pinned to the CPU build 2.13.0). Idempotent and quick when done.
set -euo pipefail
cd "$(dirname "$0")/.."

# Qt (PySide6) needs these shared libraries even offscreen; install only what is missing.
apt_pkgs=(libegl1 libgl1 libxkbcommon0 libfontconfig1 libdbus-1-3 libxcb-cursor0)
missing=()
for p in "${apt_pkgs[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ] && command -v apt-get >/dev/null 2>&1; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
fi

python3 -m pip install -q --disable-pip-version-check -e ".[dev]"
