#!/usr/bin/env bash
# One-folder desktop build: dist/prismstation/prismstation (window and command line in one).
#   bash packaging/build.sh            # installs PyInstaller into .venv if missing, then builds
# Install for one user: put dist/prismstation/ somewhere (e.g. ~/.local/lib/prismstation), link
# its prismstation onto PATH (~/.local/bin) and copy dist/prismstation/share/* to ~/.local/share/.
# Needs the environment of packaging/setup.sh (.venv with prismstation installed).
# Exit status 3: PyInstaller could not be installed.
set -euo pipefail
cd "$(dirname "$0")/.."
py=.venv/bin/python
[ -x "$py" ] || { echo "no .venv: run bash packaging/setup.sh first" >&2; exit 1; }
if ! "$py" -c "import PyInstaller" 2>/dev/null; then
  echo "installing PyInstaller into .venv"
  "$py" -m pip install -q "pyinstaller>=6.5" || { echo "cannot install PyInstaller" >&2; exit 3; }
fi
start=$(date +%s)
"$py" -m PyInstaller --noconfirm --clean --log-level WARN \
  --distpath dist --workpath build/pyinstaller packaging/prismstation.spec
install -m 644 packaging/prismstation.desktop dist/prismstation/prismstation.desktop
# icons in the freedesktop layout, ready to copy to ~/.local/share (see the .desktop entry)
for png in resources/icons/prismstation-*.png; do
  n=$(basename "$png" .png); n=${n#prismstation-}
  install -D -m 644 "$png" "dist/prismstation/share/icons/hicolor/${n}x${n}/apps/prismstation.png"
done
install -D -m 644 resources/icons/prismstation.svg dist/prismstation/share/icons/hicolor/scalable/apps/prismstation.svg
install -D -m 644 packaging/prismstation.desktop dist/prismstation/share/applications/prismstation.desktop
echo "built dist/prismstation in $(( $(date +%s) - start )) s, $(du -sh dist/prismstation | cut -f1)"
