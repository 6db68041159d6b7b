#!/usr/bin/env bash
# Installs the system libraries that the gmsh wheel links against (OpenGL/X11 client
# libraries, fontconfig), only if one is missing. Debian/Ubuntu; uses sudo when not root.
set -euo pipefail
libs="libGLU.so.1 libGL.so.1 libXrender.so.1 libXcursor.so.1 libXfixes.so.3 libXext.so.6
libXft.so.2 libfontconfig.so.1 libXinerama.so.1 libX11.so.6 libgomp.so.1"
missing=""
for lib in $libs; do
  ldconfig -p 2>/dev/null | grep -q "$lib" || missing="$missing $lib"
done
[ -z "$missing" ] && exit 0
echo "system libraries for gmsh missing:$missing; installing them" >&2
pkgs="libglu1-mesa libgl1 libxrender1 libxcursor1 libxfixes3 libxext6 libxft2 libfontconfig1
libxinerama1 libx11-6 libgomp1"
if ! command -v apt-get >/dev/null; then
  echo "no apt-get: install the packages providing$missing by hand" >&2
  exit 1
fi
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $pkgs >/dev/null
