#!/usr/bin/env bash
# One-step set-up on Debian/Ubuntu: system libraries Qt needs (even offscreen), the PROJ
# geoid grids, a virtual environment in .venv and prismstation installed into it (editable).
#   bash packaging/setup.sh          # the workstation
#   bash packaging/setup.sh --test   # plus every tool the tests use (no test skips for want of one)
set -euo pipefail
cd "$(dirname "$0")/.."
extras=""
[ "${1:-}" = "--test" ] && extras="[test]"

# proj-data holds the EGM96 geoid grid (egm96_15.gtx) the geoid tests look for
debs="python3-venv libegl1 libgl1 libx11-6 libdbus-1-3 libfontconfig1 libfreetype6 libglib2.0-0
libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1
libxcb-render-util0 libxcb-shape0 libxcb-xkb1 proj-data fonts-dejavu-core"
# the tests' own tools: pdftotext, pdftoppm and pdfimages read the PDF report back; a real
# X desktop (Xvfb, the openbox window manager, xdotool, wmctrl, xprop/xwininfo) to start,
# maximize and quit the window as a user does
[ -n "$extras" ] && debs="$debs poppler-utils xvfb xauth openbox xdotool wmctrl x11-utils"
missing=""
for p in $debs; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
if [ -n "$missing" ] && command -v apt-get >/dev/null; then
  . packaging/apt_wait.sh  # apt_get: waits for another apt's locks
  echo "installing system packages:$missing"
  apt_get update -qq
  apt_get install -y -qq --no-install-recommends $missing
fi

py=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$py" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".$extras"
# matching's compiled loops into numba's disk cache now, not at the first match (a few seconds)
.venv/bin/python -c "from prismstation.core.matching.lsm_kernel import compile_kernels; compile_kernels()"
echo "prismstation installed in .venv"
