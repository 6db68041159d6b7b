#!/usr/bin/env bash
# Checks the system libraries that the gmsh wheel links against (OpenGL/X11 client libraries,
# fontconfig, OpenMP) and, only when one is missing, installs them with apt-get: directly as
# root, through `sudo -n` (never a password prompt) otherwise. When that cannot be done it
# prints the exact command to run and exits 1. Works as any user: the check asks the dynamic
# loader itself (python3's ctypes), not ldconfig, which is not on a normal user's PATH.
set -euo pipefail
libs="GLU GL Xrender Xcursor Xfixes Xext Xft fontconfig Xinerama X11 gomp"
pkgs="libglu1-mesa libgl1 libxrender1 libxcursor1 libxfixes3 libxext6 libxft2 libfontconfig1
libxinerama1 libx11-6 libgomp1"
if ! command -v python3 >/dev/null 2>&1; then
  echo "critfric set-up: python3 (3.11 or newer) is missing; install it, e.g.:" >&2
  echo "  sudo apt-get install python3 python3-venv" >&2
  exit 1
fi
missing=$(python3 - $libs <<'PY'
import ctypes, ctypes.util, sys
def loads(name):
    path = ctypes.util.find_library(name)
    for candidate in ([path] if path else []) + [f"lib{name}.so.1", f"lib{name}.so.6",
                                                   f"lib{name}.so.2", f"lib{name}.so.3"]:
        try:
            ctypes.CDLL(candidate)
            return True
        except OSError:
            pass
    return False
print(" ".join(n for n in sys.argv[1:] if not loads(n)))
PY
)
[ -z "$missing" ] && exit 0
pkgs=$(echo $pkgs)
line="apt-get install -y --no-install-recommends $pkgs"
echo "critfric set-up: system libraries for gmsh missing: $missing" >&2
if ! command -v apt-get >/dev/null 2>&1; then
  echo "critfric set-up: no apt-get here; install the packages providing those libraries" >&2
  echo "  (Debian/Ubuntu names: $pkgs)" >&2
  exit 1
fi
if [ "$(id -u)" -eq 0 ]; then
  SUDO=""
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  SUDO="sudo -n"
else
  echo "critfric set-up: installing them needs root; run this once, then run make again:" >&2
  echo "  sudo apt-get update && sudo $line" >&2
  exit 1
fi
echo "critfric set-up: installing them: $line" >&2
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO $line -qq >/dev/null
