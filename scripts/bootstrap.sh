#!/usr/bin/env bash
# Install what safenav needs and build it, skipping whatever is already there.
#
#   bash scripts/bootstrap.sh            # system packages, .venv, editable build with test extra
#
# Works on a fresh Debian 12 (root, or a user with sudo).  A rerun installs
# nothing new; C++ changes are rebuilt incrementally on the next `import safenav`
# (scikit-build-core editable mode with a persistent build/ folder).
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}
# One package per line; '#' starts a comment.
mapfile -t DEB_PACKAGES < <(sed -e 's/#.*//' -e 's/[[:space:]]//g' -e '/^$/d' scripts/debian-packages.txt)

say() { printf '[bootstrap] %s\n' "$*"; }

# --- Debian packages --------------------------------------------------------
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
missing=()
for p in "${DEB_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
command -v "$PYTHON" >/dev/null || missing+=(python3)
if command -v "$PYTHON" >/dev/null; then
  "$PYTHON" -c "import venv, ensurepip" 2>/dev/null || missing+=(python3-venv)
  inc=$("$PYTHON" -c "import sysconfig; print(sysconfig.get_paths()['include'])")
  [ -f "$inc/Python.h" ] || missing+=(python3-dev)
fi
if [ ${#missing[@]} -gt 0 ]; then
  say "installing Debian packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  say "Debian packages: all present"
fi

# --- virtual environment and editable build ---------------------------------
if [ ! -x "$VENV/bin/python" ]; then
  say "creating $VENV"
  "$PYTHON" -m venv "$VENV"
fi
PY="$VENV/bin/python"
stamp="$VENV/.safenav-stamp"
want=$(cat pyproject.toml CMakeLists.txt | sha256sum | cut -d' ' -f1)
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && "$PY" -c "import safenav" 2>/dev/null; then
  say "safenav: installed (C++ changes rebuild on import)"
else
  say "installing build tools and safenav (editable, with the test extra)"
  "$PY" -m pip install -q --upgrade pip
  # The build requirements of pyproject.toml (the build runs without isolation).
  mapfile -t build_requires < <("$PY" -c "import tomllib; print(*tomllib.load(open('pyproject.toml', 'rb'))['build-system']['requires'], sep='\n')")
  "$PY" -m pip install -q "${build_requires[@]}"
  # ccache, installed above, keeps the objects for the pip build test, which
  # compiles the same sources again from a copy of the checkout (CMakeLists.txt
  # turns it on: SAFENAV_CCACHE).
  "$PY" -m pip install -q --no-build-isolation -Ceditable.rebuild=true -Cbuild-dir=build/{wheel_tag} -e ".[test]"
  echo "$want" > "$stamp"
fi
"$PY" -c "import safenav; print('[bootstrap] safenav', safenav.__version__, 'ready:', safenav.__file__)"
