"""Packaging checks: the Blender extension manifest, its bundled wheels, and the Python package layout.

- Blender's own extension validator (shipped inside the bpy wheel) accepts the manifest, with Blender's
  list of valid tags, and its `build` command produces a zip holding the add-on, the wheels and no
  development files.
- Every wheel the manifest lists exists, for both CPython 3.11 (Blender 4.2-5.0) and 3.13 (Blender 5.1+),
  at the versions pinned in requirements.txt (so the dev environment tests what ships).
- A non-editable wheel of the Python package (the repo root mapped to `penumbra` by pyproject.toml)
  contains every sub-package and the GLSL sources, and imports from outside the checkout.
"""
from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MANIFEST = ROOT / "blender_manifest.toml"

# Packages bundled as wheels (numpy ships with Blender and must not be bundled).
BUNDLED = ("moderngl", "glcontext", "openexr")
PYTHON_TAGS = ("cp311", "cp313")

# Development-only content that must not end up in the extension zip.
DEV_ONLY = ("tests/", "tools/", ".venv/", ".ci/", ".git/", "out/", "build/", "pyproject.toml",
            "requirements.txt")

# Shader-file suffixes that pyproject's package-data globs must ship.
SHADER_SUFFIXES = (".glsl", ".comp", ".vert", ".frag")


def _manifest() -> dict:
    with open(MANIFEST, "rb") as fh:
        return tomllib.load(fh)


def _find_bpy_scripts() -> Path | None:
    """The `scripts` folder inside the installed bpy wheel, located without importing bpy (slow)."""
    spec = importlib.util.find_spec("bpy") if "bpy" not in sys.modules else sys.modules["bpy"].__spec__
    if spec is None or not spec.submodule_search_locations:
        return None
    for location in spec.submodule_search_locations:
        for candidate in sorted(Path(location).glob("*/scripts")):
            if (candidate / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py").is_file():
                return candidate
    return None


def _validator() -> tuple[Path, Path | None]:
    """(blender_ext.py, tags.py) from the bpy wheel; PENUMBRA_BLENDER_EXT overrides the script path."""
    override = os.environ.get("PENUMBRA_BLENDER_EXT")
    scripts = _find_bpy_scripts()
    if override:
        script = Path(override)
    elif scripts is not None:
        script = scripts / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    else:
        pytest.skip("Blender's extension validator (bl_pkg/cli/blender_ext.py) was not found: the bpy "
                    "wheel is not installed in this environment (run tools/setup.sh) and "
                    "PENUMBRA_BLENDER_EXT is not set")
    if not script.is_file():
        pytest.skip(f"Blender's extension validator not found at {script}")
    tags = None
    if scripts is not None:
        tags_file = scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py"
        tags = tags_file if tags_file.is_file() else None
    return script, tags


def _run_validator(*args: str) -> subprocess.CompletedProcess:
    script, tags = _validator()
    cmd = [sys.executable, str(script), args[0]]
    if tags is not None:
        # Same tag list Blender uses for `blender --command extension validate`.
        cmd += ["--valid-tags", str(tags)]
    cmd += list(args[1:])
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def test_manifest_passes_blender_validator():
    _, tags = _validator()
    assert tags is not None, "Blender's tags.py was not found next to the validator"
    proc = _run_validator("validate", str(ROOT))
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"blender_ext.py validate failed:\n{out}"
    assert "Success" in out, out


def test_extension_zip_builds(tmp_path):
    proc = _run_validator("build", "--source-dir", str(ROOT), "--output-dir", str(tmp_path))
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"blender_ext.py build failed:\n{out}"
    manifest = _manifest()
    archive = tmp_path / f"{manifest['id']}-{manifest['version']}.zip"
    assert archive.is_file(), f"no {archive.name} in {sorted(os.listdir(tmp_path))}\n{out}"

    with zipfile.ZipFile(archive) as zf:
        names = zf.namelist()
    name_set = set(names)
    assert "blender_manifest.toml" in name_set
    assert "__init__.py" in name_set
    for wheel in manifest["wheels"]:
        assert os.path.normpath(wheel) in name_set, f"{wheel} missing from the extension zip"
    leaked = [n for n in names
              if n.startswith(DEV_ONLY) or "__pycache__/" in n or n.endswith(".pyc") or ".egg-info/" in n]
    assert not leaked, f"development files in the extension zip: {leaked[:20]}"
    shaders = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "glsl").rglob("*")
                     if p.suffix in SHADER_SUFFIXES)
    missing = [s for s in shaders if s not in name_set]
    assert not missing, f"shader sources missing from the extension zip: {missing}"
    # Validating the built archive checks the manifest as Blender sees it at install time.
    proc = _run_validator("validate", str(archive))
    assert proc.returncode == 0, proc.stdout + proc.stderr


WHEEL_RE = re.compile(r"^(?P<dist>[^-]+)-(?P<version>[^-]+)(-\d[^-]*)?-(?P<py>[^-]+)-(?P<abi>[^-]+)-"
                      r"(?P<plat>[^-]+)\.whl$")


def _listed_wheels() -> list[tuple[str, dict]]:
    wheels = _manifest().get("wheels", [])
    parsed = []
    for wheel in wheels:
        m = WHEEL_RE.match(os.path.basename(wheel))
        assert m, f"not a wheel file name: {wheel}"
        parsed.append((wheel, m.groupdict()))
    return parsed


def test_manifest_wheels_exist():
    wheels = _listed_wheels()
    assert wheels, "blender_manifest.toml lists no wheels"
    missing = [w for w, _ in wheels if not (ROOT / w).is_file()]
    assert not missing, f"wheels listed in blender_manifest.toml are missing (run tools/setup.sh): {missing}"
    for wheel, _ in wheels:
        assert wheel.startswith("./wheels/"), wheel
        with zipfile.ZipFile(ROOT / wheel) as zf:  # a real wheel, not an LFS pointer or HTML page
            assert any(n.endswith(".dist-info/WHEEL") for n in zf.namelist()), wheel


def test_manifest_wheels_cover_cp311_and_cp313():
    by_dist: dict[str, dict[str, str]] = {}
    for wheel, info in _listed_wheels():
        dist = info["dist"].lower().replace("_", "-")
        assert dist != "numpy", "numpy is bundled with Blender: do not ship it"
        assert info["py"] in PYTHON_TAGS and info["abi"] == info["py"], f"unexpected Python tags: {wheel}"
        assert all(p.startswith("manylinux") and p.endswith("x86_64") for p in info["plat"].split(".")), \
            f"not a manylinux x86_64 wheel (manifest platforms = linux-x64): {wheel}"
        assert info["py"] not in by_dist.get(dist, {}), f"two {dist} wheels for {info['py']}"
        by_dist.setdefault(dist, {})[info["py"]] = info["version"]

    assert sorted(by_dist) == sorted(BUNDLED), f"bundled packages: {sorted(by_dist)}"
    for dist, versions in by_dist.items():
        assert sorted(versions) == sorted(PYTHON_TAGS), f"{dist}: wheels for {sorted(versions)} only"
        assert len(set(versions.values())) == 1, f"{dist}: different versions per Python {versions}"


def test_bundled_wheel_versions_match_requirements():
    """The dev venv (requirements.txt) must test the same versions the extension ships."""
    pins = {}
    for line in (ROOT / "requirements.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if "==" in line:
            name, version = line.split("==", 1)
            pins[name.strip().lower().replace("_", "-")] = version.strip()
    for wheel, info in _listed_wheels():
        dist = info["dist"].lower().replace("_", "-")
        assert pins.get(dist) == info["version"], \
            f"{wheel}: requirements.txt pins {dist}=={pins.get(dist)}, manifest ships {info['version']}"


# --- Python package layout ---------------------------------------------------------------------------------

_COPY_IGNORE = shutil.ignore_patterns(".venv", ".git", ".ci", "wheels", "out", "build", "dist", ".cache",
                                      "*.egg-info", "__pycache__", "*.pyc", "*.zip", "*.exr", "*.png")


def _source_packages() -> set[str]:
    """Dotted names of every package directory (with __init__.py) in the checkout."""
    packages = set()
    for init in ROOT.rglob("__init__.py"):
        rel = init.parent.relative_to(ROOT)
        if any(part.startswith(".") or part in ("build", "dist", "out", "wheels") or part.endswith(".egg-info")
               for part in rel.parts):
            continue
        packages.add(".".join(("penumbra",) + rel.parts))
    return packages


def test_python_wheel_layout_and_import(tmp_path):
    from importlib.metadata import version

    setuptools_version = tuple(int(x) for x in re.findall(r"\d+", version("setuptools"))[:2])
    assert setuptools_version >= (77, 0), \
        f"setuptools {version('setuptools')} is too old for pyproject.toml (needs >=77): run tools/setup.sh"

    src = tmp_path / "checkout-not-named-penumbra"
    shutil.copytree(ROOT, src, ignore=_COPY_IGNORE)
    # Probe files check the package-data globs for each shader suffix, at any depth.
    probes = [f"glsl/zz_probe/nested/probe{s}" for s in SHADER_SUFFIXES]
    for probe in probes:
        (src / probe).parent.mkdir(parents=True, exist_ok=True)
        (src / probe).write_text("// packaging probe\n")

    dist = tmp_path / "dist"
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
                           "--disable-pip-version-check", "-w", str(dist), str(src)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (wheel,) = dist.glob("penumbra-*.whl")

    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
    expected = {f"penumbra/{p}" for p in probes}
    expected |= {"penumbra/" + p.relative_to(ROOT).as_posix() for p in (ROOT / "glsl").rglob("*")
                 if p.suffix in SHADER_SUFFIXES}
    expected |= {p.replace(".", "/") + "/__init__.py" for p in _source_packages()}
    expected.add("penumbra/blender_manifest.toml")
    missing = sorted(expected - names)
    assert not missing, f"missing from the wheel (pyproject packages / package-data): {missing}"
    stray = sorted(n for n in names if not n.startswith(("penumbra/", "penumbra-")))
    assert not stray, f"files outside the penumbra package: {stray}"

    target = tmp_path / "site"
    proc = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index",
                           "--disable-pip-version-check", "--target", str(target), str(wheel)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr

    # Import from a neutral directory, with the installed copy first on the path (ahead of any editable
    # install of the checkout).
    env = dict(os.environ, PYTHONPATH=str(target))
    code = ("import os, sys, penumbra, penumbra.engine.core.snapshot\n"
            "print(os.path.dirname(penumbra.__file__))\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert Path(proc.stdout.strip().splitlines()[-1]) == target / "penumbra"
