"""Anti-aliasing with one visibility sample per pixel (Schwarz & Stamminger 2008, §7): it lowers the error at
silhouettes against a box-filtered Cycles reference for every technique, and leaves what it must not touch."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402
from penumbra.engine.measure import reference  # noqa: E402
from penumbra.engine.measure.studies import msaa as study  # noqa: E402
from penumbra.engine.render import pipeline  # noqa: E402

SIZE = 64


def _white_scene(name):
    sc = study._scene(name, SIZE)
    return sc, study.white(extract(bpy.context.evaluated_depsgraph_get(), sc))


@pytest.fixture(scope="module")
def silhouette():
    sc, snap = _white_scene("silhouette")
    return snap, reference.cycles_visibility(sc, samples=256, filter_type="BOX")


@pytest.mark.heavy
@pytest.mark.parametrize("technique", list(pipeline.TECHNIQUES))
def test_antialiasing_lowers_the_edge_error_against_box_filtered_cycles(technique, silhouette):
    """Stacked plates over a floor at 64²: Combined at the silhouette pixels is closer to Cycles' box-filtered
    (1 px) render with anti-aliasing than without, for every technique."""
    snap, box = silhouette
    off = pipeline.render(snap, RenderSettings(technique=technique, antialiasing=False))
    on = pipeline.render(snap, RenderSettings(technique=technique))
    edges = study.edge_pixels(off.passes["Depth"][..., 0], pipeline.BACKGROUND_DEPTH)
    e_off, e_on = study.edge_errors(off.passes, box, edges), study.edge_errors(on.passes, box, edges)
    print(technique, e_off, e_on)
    assert e_off["edge_pixels"] > 200
    assert e_on["edge_error"] < e_off["edge_error"]


def test_the_papers_first_sample_visibility_also_lowers_the_edge_error(silhouette):
    snap, box = silhouette
    off = pipeline.render(snap, RenderSettings(technique="PCSS", antialiasing=False))
    first = pipeline.render(snap, RenderSettings(technique="PCSS", aa_visibility_sample="FIRST"))
    edges = study.edge_pixels(off.passes["Depth"][..., 0], pipeline.BACKGROUND_DEPTH)
    assert study.edge_errors(first.passes, box, edges)["edge_error"] < \
        study.edge_errors(off.passes, box, edges)["edge_error"]


@pytest.mark.parametrize("name", ["silhouette", "plane"])
def test_antialiasing_changes_only_silhouette_pixels_and_no_measurement_pass(name):
    """With the pixel-centre visibility sample, the techniques' input is the frame's without anti-aliasing:
    Depth and Visibility are bit-identical, and so is Combined away from silhouettes (flat faces here: every
    sample there repeats its pixel's fragment). Off, no multisampled G-buffer is drawn at all."""
    _, snap = _white_scene(name)
    off = pipeline.render(snap, RenderSettings(technique="PCSS", antialiasing=False))
    on = pipeline.render(snap, RenderSettings(technique="PCSS"))
    assert "gbuffer_msaa" not in off.timings and "gbuffer_msaa" in on.timings
    for p in ("Depth", "Visibility"):
        assert np.array_equal(on.passes[p], off.passes[p]), p
    edges = study.edge_pixels(off.passes["Depth"][..., 0], pipeline.BACKGROUND_DEPTH)
    changed = np.any(on.passes["Combined"] != off.passes["Combined"], axis=-1)
    assert changed.any()                   # the silhouettes did change
    assert not (changed & ~edges).any()


def test_the_depth_threshold_picks_neighbour_visibility_at_silhouettes_only(silhouette):
    """τ = 1 gives every sample its pixel's visibility (no interpolation): that changes Combined somewhere, and
    only at silhouettes, where a sample of another surface takes the visibility of the closest-depth neighbour."""
    snap, _ = silhouette
    tau = pipeline.render(snap, RenderSettings(technique="PCSS"))
    own = pipeline.render(snap, RenderSettings(technique="PCSS", aa_depth_threshold=1.0))
    edges = study.edge_pixels(tau.passes["Depth"][..., 0], pipeline.BACKGROUND_DEPTH)
    changed = np.any(tau.passes["Combined"] != own.passes["Combined"], axis=-1)
    assert changed.any() and not (changed & ~edges).any()


def test_edge_pixels_mark_coverage_steps_and_depth_creases_not_a_slanted_plane():
    h, w = 16, 16
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    plane = 1.0 / (0.1 + 0.01 * xx + 0.02 * yy)            # a plane: inverse depth affine in the pixel
    assert not study.edge_pixels(plane, 1e10).any()
    stepped = plane.copy()
    stepped[:, 8:] *= 0.5                                   # an occluder in front of the right half
    cols = np.flatnonzero(study.edge_pixels(stepped, 1e10).any(axis=0))
    assert cols.min() >= 6 and cols.max() <= 9
    holed = plane.copy()
    holed[4, 4] = 1e10                                      # one background pixel
    e = study.edge_pixels(holed, 1e10)
    assert e[3:6, 3:6].all() and e.sum() <= 25


def test_the_viewports_first_frame_goes_without_antialiasing():
    from penumbra.engine.render.viewport import coarse_settings
    assert RenderSettings().antialiasing
    assert not coarse_settings(RenderSettings(), 256).antialiasing


def test_the_viewports_refined_frame_is_antialiased_like_the_final_render():
    from penumbra.engine.blender.viewport_sync import BlenderViewport
    sc = study._scene("silhouette", SIZE)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    snap = extract(depsgraph, sc)
    final = pipeline.render(snap, RenderSettings(technique="PCSS"))
    session = BlenderViewport()
    try:
        session.sync(depsgraph)
        session.request(snap.camera, RenderSettings(technique="PCSS"))
        frame = session.wait()
        assert not frame.coarse and "gbuffer_msaa" in frame.timings
        # object-space buffers drawn with model matrices vs world-space vertices: float32 rounding only
        assert np.mean(np.abs(frame.passes["Combined"] - final.passes["Combined"])) < 1e-3
    finally:
        session.free()
