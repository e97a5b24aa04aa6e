"""PVSM (Shen et al. 2011), fixed-resolution mode: the closed form of parallel planes, finite results at the
formulas' singular points (α → 0, α → ∞, grazing pixel footprints, a degenerate Cholesky factorisation) and
the fully-lit skip."""
from dataclasses import replace

import numpy as np
import pytest

from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.core.snapshot import Camera
from penumbra.engine.measure.stress import look_at, perspective
from penumbra.engine.render import pipeline
from penumbra.engine.techniques import pvsm
from penumbra.tests.synthetic import floating_plane
from penumbra.tests.test_pipeline import _ground_depth, exact_area_visibility, ground_points

SIZE = 64


def _render(snap, **options):
    settings = RenderSettings(technique="PVSM", shadow_map_size=options.pop("shadow_map_size", 1024))
    return pipeline.render(snap, settings.with_(**options))


def _visibility(result):
    v = result.passes["Visibility"][..., 0]
    for name, array in result.passes.items():
        assert np.isfinite(array).all(), f"non-finite values in {name}"
    assert v.min() >= 0.0 and v.max() <= 1.0, (v.min(), v.max())
    return v


@pytest.fixture(scope="module")
def plane():
    snap = floating_plane(SIZE)
    pts = ground_points(snap)
    return snap, pts, exact_area_visibility(pts, 0.5, 0.5, 1.0, 3.0)


def _ground_error(snap, pts, exact, result):
    on_ground = np.abs(result.passes["Depth"][..., 0] - _ground_depth(snap, pts)) < 1e-3
    return np.abs(_visibility(result) - exact), on_ground


def test_closed_form_without_antialiasing(plane):
    """Parallel planes: z-averaging finds the occluder's exact depth, so Eq. 2's exact box filtering leaves
    only the map's discretisation (a 1024² map; kernels wider than the cap read every 2^l-th texel)."""
    snap, pts, exact = plane
    err, on_ground = _ground_error(snap, pts, exact, _render(snap, pvsm_antialiasing=False,
                                                              pvsm_weighting="UNIFORM"))
    penumbra_err = err[on_ground & (exact < 0.99)]
    assert penumbra_err.size > 300
    print("PVSM vs closed form: mean", penumbra_err.mean(), "p99", np.percentile(penumbra_err, 99))
    assert penumbra_err.mean() < 0.01, penumbra_err.mean()
    assert np.percentile(penumbra_err, 99) < 0.05


def test_antialiasing_stays_close_to_the_closed_form(plane):
    """The pixel footprint widens the kernel by less than a pixel: the error may grow a little, not more."""
    snap, pts, exact = plane
    err, on_ground = _ground_error(snap, pts, exact, _render(snap, pvsm_weighting="UNIFORM",
                                                              pvsm_antialiasing=True))
    assert err[on_ground & (exact < 0.99)].mean() < 0.02


def test_fully_lit_skip_never_darkens_a_lit_pixel(plane):
    """Pixels the closed form calls fully lit are exactly 1 with the skip, and the skip never makes a pixel
    darker than the full filter."""
    snap, pts, exact = plane
    with_skip = _render(snap, pvsm_skip_lit=True)
    without = _render(snap, pvsm_skip_lit=False)
    on_ground = np.abs(with_skip.passes["Depth"][..., 0] - _ground_depth(snap, pts)) < 1e-3
    v_skip, v_full = _visibility(with_skip), _visibility(without)
    lit = on_ground & (exact >= 1.0)
    assert lit.sum() > 1000
    assert (v_skip[lit] == 1.0).all(), v_skip[lit].min()
    assert (v_skip >= v_full - 1e-6).all()


@pytest.mark.parametrize("name, occ_height, light_size", [
    ("contact", 0.001, 1.0),        # α → 0: the occluder 1 mm over the ground
    ("at_light", 2.999, 1.0),       # α → ∞: 1 mm under the light, as wide as it: the ground is dark
    ("point_like", 1.0, 1e-6),      # the light filter vanishes: without AA the kernel is degenerate
])
@pytest.mark.parametrize("aa", [False, True])
def test_singular_filters_stay_finite(name, occ_height, light_size, aa):
    snap = floating_plane(SIZE, occluder_height=occ_height, light_size=light_size)
    v = _visibility(_render(snap, pvsm_antialiasing=aa, pvsm_weighting="UNIFORM"))
    hard = pipeline.render(snap, RenderSettings(technique="HARD", shadow_map_size=1024))
    if name == "at_light":      # the closed form: dark wherever the ground is seen under the light
        pts = ground_points(snap)
        exact = exact_area_visibility(pts, light_size / 2, 0.5, occ_height, 3.0)
        on_ground = np.abs(hard.passes["Depth"][..., 0] - _ground_depth(snap, pts)) < 1e-3
        dark = on_ground & (exact < 0.01)
        assert dark.sum() > 500 and np.mean(v[dark] < 0.05) > 0.95, np.mean(v[dark] < 0.05)
    if name == "point_like":    # HARD's shadow, to within a texel's worth of edge pixels
        assert v.min() == 0.0
        assert np.mean(np.abs(v - hard.passes["Visibility"][..., 0]) > 0.5) < 0.02
    if name == "contact":       # (the contact umbra hides under the occluder, and the bias leaks under it)
        assert (v == 1.0).mean() > 0.3


def _grazing(snap, height):
    """The same scene seen from `height` metres over the ground, looking along it: the pixel footprints
    through the ground's tangent plane stretch to near-parallel rays at the horizon."""
    cam = snap.camera
    world = look_at((0.0, -4.0, height), (0.0, 0.0, 0.0))
    return replace(snap, camera=Camera("Camera", np.linalg.inv(world), perspective(np.radians(60), 1.0, 0.01, 100.0),
                                       cam.width, cam.height))


@pytest.mark.parametrize("height", [0.3, 0.02])
def test_grazing_footprints_stay_finite(height):
    snap = _grazing(floating_plane(SIZE, ground_half=40.0), height)
    v = _visibility(_render(snap, pvsm_resolution="DYNAMIC", pvsm_antialiasing=True))
    hard = _visibility(pipeline.render(snap, RenderSettings(technique="HARD", shadow_map_size=1024)))
    shadow, hard_shadow = (v < 0.5).mean(), (hard < 0.5).mean()
    assert 0.5 * hard_shadow <= shadow <= 1.5 * hard_shadow, (shadow, hard_shadow)


def test_degenerate_cholesky_matches_the_hard_edge():
    """With a near-point light and anti-aliasing on, the filter is the pixel footprint alone (m00 > 0,
    but the light's part of the variance is zero): the soft filter of a sharp edge can only blur it by about
    a pixel, so it agrees with the hard shadow away from the edge."""
    snap = floating_plane(SIZE, light_size=1e-6)
    v_aa = _visibility(_render(snap, pvsm_antialiasing=True))
    v_hard = _visibility(pipeline.render(snap, RenderSettings(technique="HARD", shadow_map_size=1024)))
    assert np.mean(np.abs(v_aa - v_hard) > 0.5) < 0.01
    assert 0.0 < np.mean((v_aa > 0.02) & (v_aa < 0.98)) < 0.05, "anti-aliasing leaves a thin soft edge"


def test_perceptual_metric_is_the_papers_cubic_held_to_its_range():
    """§5.1: ρ_dyn(x) = 0.667 + 0.7794x + 0.3967x² − 0.02716x³ at x = log2 n, flat outside 1 … 512 pixels
    (ρ_static's cubic turns down past x ≈ 7.64, so it is held there)."""
    assert pvsm.rho(8.0) == pytest.approx(0.667 + 0.7794 * 3 + 0.3967 * 9 - 0.02716 * 27)
    assert pvsm.rho(0.0) == pvsm.rho(1.0) and pvsm.rho(1e9) == pvsm.rho(512.0)
    n = 2.0 ** np.linspace(0, 9, 50)
    for kind in ("DYNAMIC", "STATIC", "LINEAR"):
        assert np.all(np.diff(pvsm.rho(n, kind)) >= 0), kind
