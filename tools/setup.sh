#!/usr/bin/env bash
# Idempotent development set-up for Penumbra. Safe to run again: work already done is skipped.
#
#   1. System libraries for moderngl's headless EGL backend (Debian/Ubuntu: installed with apt-get only
#      when missing and only when running as root; otherwise the command to run is printed).
#   2. .venv in the repository root with Python 3.11 (bpy 5.0.1 requires exactly 3.11).
#   3. Pinned requirements (requirements.txt) and the project itself in editable mode (`import penumbra`).
#      A stamp file keyed on requirements.txt, pyproject.toml and the interpreter skips this when current.
#   4. The Python wheels bundled with the Blender extension (listed in blender_manifest.toml, under
#      wheels/), downloaded from PyPI when missing.
#   5. A smoke test of the EGL context (informative only; the test suite does the real checks).
#
# Environment: PENUMBRA_PYTHON=/path/to/python3.11 to choose the interpreter.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
VENV="$ROOT/.venv"
STAMP="$VENV/.penumbra-setup-stamp"

log() { echo "[setup] $*"; }
warn() { echo "[setup] WARNING: $*" >&2; }
die() { echo "[setup] ERROR: $*" >&2; exit 1; }

quiet() {
    # quiet CMD...: run CMD, keeping its output out of the way unless it fails.
    local log_file rc=0
    log_file="$(mktemp)"
    "$@" >"$log_file" 2>&1 || rc=$?
    if [ "$rc" -ne 0 ]; then
        echo "[setup] command failed (exit $rc): $*" >&2
        tail -n 40 "$log_file" >&2
    fi
    rm -f "$log_file"
    return "$rc"
}

is_root() { [ "$(id -u)" -eq 0 ]; }
have() { command -v "$1" >/dev/null 2>&1; }

APT_UPDATED=0
apt_install() {
    # apt_install PKG...: install Debian packages (root only), printing what is done.
    if [ "$APT_UPDATED" -eq 0 ]; then
        log "apt-get update"
        DEBIAN_FRONTEND=noninteractive apt-get update -qq
        APT_UPDATED=1
    fi
    log "apt-get install --no-install-recommends $*"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}

deb_missing() {
    # deb_missing PKG...: print the packages that are not installed.
    local p
    for p in "$@"; do
        if [ "$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || true)" != "installed" ]; then
            echo "$p"
        fi
    done
}

# ---------------------------------------------------------------------------------------------------------
# 1. EGL / Mesa system libraries.
# glcontext's EGL backend dlopens libEGL.so.1 and libGL.so.1 (both from glvnd); glvnd then loads the Mesa
# EGL vendor library, which renders with llvmpipe on machines without a GPU:
#   libegl1          /usr/lib/x86_64-linux-gnu/libEGL.so.1            (glvnd EGL dispatch)
#   libgl1           /usr/lib/x86_64-linux-gnu/libGL.so.1             (glvnd GL dispatch, pulls libglx0)
#   libegl-mesa0     libEGL_mesa.so.0 + glvnd/egl_vendor.d/50_mesa.json (Mesa EGL vendor, pulls libgbm1)
#   libgl1-mesa-dri  dri/swrast_dri.so                               (llvmpipe software rasteriser)
EGL_PKGS=(libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri)
if have dpkg-query; then
    mapfile -t missing < <(deb_missing "${EGL_PKGS[@]}")
    if [ "${#missing[@]}" -eq 0 ]; then
        log "EGL/Mesa libraries present (${EGL_PKGS[*]})"
    elif is_root && have apt-get; then
        log "installing missing EGL/Mesa libraries: ${missing[*]}"
        apt_install "${missing[@]}"
    else
        warn "missing EGL/Mesa libraries: ${missing[*]}"
        warn "install them with: sudo apt-get install --no-install-recommends ${missing[*]}"
    fi
else
    log "not a Debian-based system: make sure libEGL.so.1, libGL.so.1 and a Mesa (or GPU vendor) EGL driver are installed"
fi

# ---------------------------------------------------------------------------------------------------------
# 2. Python 3.11 and the virtual environment.
is_py311() { "$1" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' >/dev/null 2>&1; }

find_python() {
    local c
    for c in "${PENUMBRA_PYTHON:-}" python3.11 /usr/bin/python3.11 /usr/local/bin/python3.11 python3; do
        [ -n "$c" ] || continue
        if have "$c" && is_py311 "$c"; then
            command -v "$c"
            return 0
        fi
    done
    return 1
}

venv_ok() { [ -x "$VENV/bin/python" ] && is_py311 "$VENV/bin/python" && "$VENV/bin/python" -m pip --version >/dev/null 2>&1; }

if venv_ok; then
    log "virtual environment present: $VENV ($("$VENV/bin/python" --version))"
else
    PY="$(find_python || true)"
    if [ -z "$PY" ] && is_root && have apt-get && have apt-cache \
            && apt-cache show python3.11 >/dev/null 2>&1; then
        log "Python 3.11 not found: installing it with apt-get"
        apt_install python3.11 python3.11-venv
        PY="$(find_python || true)"
    fi
    [ -n "$PY" ] || die "Python 3.11 not found (bpy 5.0.1 needs exactly Python 3.11).
  Install it (Debian 12: apt-get install python3.11 python3.11-venv; or pyenv install 3.11)
  or point PENUMBRA_PYTHON at a python3.11 interpreter, then run tools/setup.sh again."
    if [ -e "$VENV" ]; then
        log "removing unusable $VENV (not a working Python 3.11 venv)"
        rm -rf "$VENV"
    fi
    log "creating $VENV with $PY ($("$PY" --version 2>&1))"
    if ! "$PY" -m venv "$VENV" 2>/dev/null; then
        rm -rf "$VENV"
        if is_root && have apt-get && have dpkg-query && [ "$PY" = /usr/bin/python3.11 ]; then
            log "venv/ensurepip missing for the system Python: installing python3.11-venv"
            apt_install python3.11-venv
            "$PY" -m venv "$VENV"
        else
            die "'$PY -m venv' failed (on Debian/Ubuntu install python3.11-venv)"
        fi
    fi
    rm -f "$STAMP"
fi
VPY="$VENV/bin/python"

# ---------------------------------------------------------------------------------------------------------
# 3. Requirements and the editable install, skipped when the stamp matches.
stamp_key() {
    {
        cat requirements.txt pyproject.toml
        "$VPY" -c 'import sys; print(sys.version)'
        echo "$ROOT"
    } | sha256sum | cut -d' ' -f1
}

penumbra_importable() {
    # The editable install must resolve `penumbra` to this checkout, from any working directory.
    (cd / && "$VPY" -c 'import os, sys, penumbra
sys.exit(0 if os.path.realpath(os.path.dirname(penumbra.__file__)) == os.path.realpath(sys.argv[1]) else 1)' \
        "$ROOT") >/dev/null 2>&1
}

KEY="$(stamp_key)"
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$KEY" ] && penumbra_importable; then
    log "Python requirements up to date (stamp $STAMP)"
else
    log "installing Python requirements (requirements.txt) into $VENV"
    quiet "$VPY" -m pip install -q --disable-pip-version-check -r requirements.txt
    log "installing penumbra in editable mode (pip install -e .)"
    # Build deps (setuptools) are pinned in requirements.txt, so no isolated build env is needed.
    quiet "$VPY" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e .
    penumbra_importable || die "'import penumbra' does not resolve to $ROOT after the editable install"
    echo "$KEY" > "$STAMP"
    log "Python requirements installed"
fi

# ---------------------------------------------------------------------------------------------------------
# 4. Wheels bundled with the Blender extension (cp311 for Blender 4.2-5.0, cp313 for Blender 5.1+).
mapfile -t missing_wheels < <("$VPY" - <<'EOF'
import os, tomllib
with open("blender_manifest.toml", "rb") as fh:
    for w in tomllib.load(fh).get("wheels", []):
        if not os.path.isfile(w):
            print(w)
EOF
)
if [ "${#missing_wheels[@]}" -eq 0 ]; then
    log "extension wheels present (wheels/)"
else
    mkdir -p wheels
    for w in "${missing_wheels[@]}"; do
        f="$(basename "$w")"
        IFS=- read -r dist ver pytag _ <<<"$f"
        pyver="${pytag#cp}"; pyver="${pyver:0:1}.${pyver:1}"
        log "downloading $dist==$ver for Python $pyver -> $w"
        tmp="$(mktemp -d)"
        if quiet "$VPY" -m pip download -q --disable-pip-version-check --only-binary=:all: --no-deps \
                --python-version "$pyver" --implementation cp \
                --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
                --platform manylinux2014_x86_64 --platform manylinux_2_5_x86_64 --platform manylinux1_x86_64 \
                -d "$tmp" "$dist==$ver" && [ -f "$tmp/$f" ]; then
            mv "$tmp/$f" "$w"
        else
            warn "could not download $f (got: $(ls "$tmp" 2>/dev/null | tr '\n' ' ')); the extension build will lack it"
        fi
        rm -rf "$tmp"
    done
fi

# ---------------------------------------------------------------------------------------------------------
# 5. EGL smoke test (informative).
if out="$(cd / && "$VPY" -c "import moderngl
ctx = moderngl.create_standalone_context(backend='egl')
print(ctx.info['GL_RENDERER'], '| OpenGL', ctx.version_code)" 2>&1)"; then
    log "EGL context OK: $out"
else
    warn "could not create a headless EGL context (GPU tests will fail):"
    echo "$out" | tail -3 >&2
fi
log "done"
