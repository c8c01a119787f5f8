#!/usr/bin/env bash
# Set up OutCast on a fresh machine: system libraries Qt needs, then the package with the
# training/test extras (torch pinned to 2.13.0: the CPU build where pip's configuration offers it;
# README.md, "Quick start"). Idempotent and quick when done.
set -euo pipefail
cd "$(dirname "$0")/.."

# Qt (PySide6) needs the first line of shared libraries even offscreen; a real X display (the xcb
# platform plugin, checked with `ldd .../platforms/libqxcb.so`) needs the xcb ones too; Xvfb runs
# the test that starts the app on a real (virtual) X server; desktop-file-validate and appstreamcli
# check the packaging files (tests/packaging). Install only what is missing.
apt_pkgs=(libegl1 libgl1 libxkbcommon0 libfontconfig1 fonts-dejavu-core libdbus-1-3
  libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 libxcb-image0 libxcb-randr0 libxcb-render-util0
  libxcb-shape0 libxcb-xkb1 libxcb-xfixes0 libxcb-sync1 libxcb-shm0 libxcb-glx0 libx11-xcb1
  libxkbcommon-x11-0
  xvfb
  desktop-file-utils appstream)
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
