"""The command line refuses bad numbers with their allowed range (one line, exit 2, before any scene is
loaded), chooses the output format from the extension, lists every setting in --help, and keeps the old flag
spellings as deprecated aliases."""
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from penumbra.engine import cli
from penumbra.engine.core.settings import SHARED
from penumbra.engine.techniques import TECHNIQUES

ROOT = Path(__file__).resolve().parent.parent


def _run(argv, capsys):
    """(exit status, stdout, stderr) of cli.main in this process."""
    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


RENDER = ["render", "--scene", "plane", "--out", "x.exr"]


@pytest.mark.parametrize("argv, expected", [
    (RENDER + ["--resolution", "0", "0"], "argument --resolution: 0 is out of range (4 … 65536)"),
    (RENDER + ["--resolution", "-5", "64"], "argument --resolution: -5 is out of range (4 … 65536)"),
    (RENDER + ["--resolution", "1", "1"], "argument --resolution: 1 is out of range (4 … 65536)"),
    (RENDER + ["--light-samples", "0"], "argument --light-samples: 0 is out of range (1 … 4096)"),
    (RENDER + ["--map-size", "0"], "argument --map-size: 0 is out of range (16 … 16384)"),
    (RENDER + ["--set", "debug_passes=maybe"], "setting 'debug_passes' expects true or false, got 'maybe'"),
    (RENDER + ["--set", "pcf_taps=0"], "Setting 'pcf_taps' = 0 is out of range (1 … 33)"),
    (RENDER + ["--set", "shadow_map_size=3"], "Setting 'shadow_map_size' = 3 is out of range (16 … 16384)"),
    (["compare", "--scene", "plane", "--cycles-samples", "0"],
     "argument --cycles-samples: 0 is out of range (1 … 16777216)"),
    (["render", "--scene", "plane", "--out", "x.jpg"],
     "'x.jpg': the format follows the extension; use .exr or .png"),
    (["render", "--scene", "plane", "--out", "frame"], "'frame': the format follows the extension"),
    (RENDER + ["--png", "x.tif"], "'x.tif': the format follows the extension; use .png"),
    (["bench", "--out", "o", "--cycles-samples", "0"],
     "argument --cycles-samples: 0 is out of range (1 … 16777216)"),
    (["bench", "--out", "o", "--cycles-samples", "1,4,16"],
     "the Cycles peer's list of counts is now --cycles-peer-samples"),
    (["bench", "--out", "o", "--repeats", "0"], "argument --repeats: 0 is out of range (≥ 1)"),
    (["bench", "--scaling", "--out", "o", "--max-pixels", "0"], "argument --max-pixels: 0 is out of range (≥ 1)"),
])
def test_bad_numbers_are_refused_with_the_allowed_range(argv, expected, capsys):
    code, out, err = _run(argv, capsys)
    assert code == 2, (argv, out, err)
    assert expected in err
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err


def test_refusal_from_a_real_process_is_one_line_with_status_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "penumbra", "render", "--scene", "plane", "--resolution", "1", "1",
                        "--out", str(tmp_path / "x.exr")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        "python -m penumbra render: argument --resolution: 1 is out of range (4 … 65536) (see --help)"]
    assert not (tmp_path / "x.exr").exists()


def test_ranges_are_blenders_own():
    bpy = pytest.importorskip("bpy")
    from penumbra.engine.core.arguments import CYCLES_SAMPLES_RANGE, RESOLUTION_RANGE
    prop = bpy.types.RenderSettings.bl_rna.properties["resolution_x"]
    assert (prop.hard_min, prop.hard_max) == RESOLUTION_RANGE
    samples = bpy.context.scene.cycles.bl_rna.properties["samples"]
    assert (samples.hard_min, samples.hard_max) == CYCLES_SAMPLES_RANGE


@pytest.mark.parametrize("argv, dest, value, notice", [
    (RENDER + ["--samples", "8"], "light_samples", 8, "--samples is deprecated; use --light-samples"),
    (["bench", "--out", "o", "--reference-samples", "512"], "cycles_samples", 512,
     "--reference-samples is deprecated; use --cycles-samples"),
])
def test_old_flags_still_work_and_say_so(argv, dest, value, notice, capsys):
    args = cli.build_parser().parse_args(argv)
    assert getattr(args, dest) == value
    err = capsys.readouterr().err
    assert err.strip() == f"penumbra: {notice}"
    assert "--samples" not in cli.build_parser().parse_args(RENDER).__dict__    # hidden: no own destination


def test_renamed_setting_names_are_mapped_with_a_notice(capsys):
    assert cli.parse_overrides(["reference_samples=8", "reference_weighted=off"]) == {
        "averaged_light_samples": 8, "averaged_weighted": False}
    assert "now called 'averaged_light_samples'" in capsys.readouterr().err


def test_render_help_lists_every_setting_with_default_and_range(capsys):
    code, out, _ = _run(["render", "--help"], capsys)
    assert code == 0
    epilog = out[out.index("settings:"):]
    for opt in list(SHARED) + [o for t in TECHNIQUES.values() for o in t.options]:
        default = str(opt.default).lower() if isinstance(opt.default, bool) else str(opt.default)
        assert re.search(rf"^  {opt.name} = {re.escape(default)}   \({re.escape(opt.allowed())}", epilog, re.M), \
            opt.name
    assert "technique = PCSS" in epilog
    assert not [line for line in out.splitlines() if "--samples" in line.split()]       # the alias is hidden
    code, out, _ = _run(["compare", "--help"], capsys)
    assert re.search(r"Cycles samples of the reference\s+\(default:\s+256\)", out)


def test_version_and_console_script(capsys):
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    code, out, _ = _run(["--version"], capsys)
    assert code == 0 and out.strip() == f"penumbra {project['version']}"
    module, _, name = project["scripts"]["penumbra"].partition(":")
    assert module == "penumbra.engine.cli" and getattr(cli, name) is cli.main


def test_out_png_writes_a_png_of_the_image(tmp_path):
    pytest.importorskip("bpy")
    out = tmp_path / "frame.png"
    r = subprocess.run([sys.executable, "-m", "penumbra", "render", "--scene", "plane", "--technique", "HARD",
                        "--resolution", "40", "24", "--out", str(out)], capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert (int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")) == (40, 24)   # IHDR
