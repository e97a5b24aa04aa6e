"""engine.metrics: hand-computed values, masks, NaNs, the robust max. numpy only, fast."""
import math

import numpy as np
import pytest

from penumbra.engine.measure import metrics as M


def _field(n=4):
    return np.ones((n, n)), np.ones((n, n))


def test_compare_hand_values():
    v, ref = _field()
    ref[0, 0] = 0.0
    v[0, 0] = 0.3       # both in shadow: |d| = 0.3, same side of 0.5
    v[0, 1] = 0.95      # only v below 0.99: counts as penumbra, |d| = 0.05
    r = M.compare(v, ref, np.ones((4, 4), bool))
    assert r["n_mask"] == 16
    assert r["n_shadow"] == 2
    assert r["mae_shadow"] == pytest.approx((0.3 + 0.05) / 2)
    assert r["mae"] == pytest.approx((0.3 + 0.05) / 16)
    assert r["rmse"] == pytest.approx(math.sqrt((0.09 + 0.0025) / 16))
    assert r["pixel_match"] == pytest.approx(1.0)
    # border windows hold only the in-image pixels: the corner window {0.3, 0.05, 0, 0} has median
    # (0 + 0.05) / 2, every other window's median is 0
    assert r["max_abs"] == pytest.approx(0.025)


def test_pixel_match_counts_side_changes():
    v, ref = _field()
    ref[0, 0] = 0.0
    v[0, 0] = 0.6       # lit side of 0.5 while the reference is dark
    ref[3, 3] = 0.49
    v[3, 3] = 0.5       # exactly 0.5 counts as the lit side
    r = M.compare(v, ref)
    assert r["pixel_match"] == pytest.approx(14 / 16)


def test_mask_restricts_every_metric():
    v, ref = _field(5)
    v[:, :2] = 0.0      # big errors, but outside the mask
    mask = np.zeros((5, 5), bool)
    mask[:, 2:] = True
    v[2, 3] = 0.8       # the only in-mask error
    r = M.compare(v, ref, mask)
    assert r["n_mask"] == 15
    assert r["n_shadow"] == 1
    assert r["mae_shadow"] == pytest.approx(0.2)
    assert r["rmse"] == pytest.approx(math.sqrt(0.04 / 15))
    assert r["pixel_match"] == 1.0
    # unmasked pixels do not enter the median windows either: max_abs stays 0, not 1
    assert r["max_abs"] == pytest.approx(0.0)


def test_max_abs_median_ignores_single_outlier_but_keeps_regions():
    v = np.zeros((9, 9))
    ref = np.zeros((9, 9))
    v[4, 4] = 1.0                       # one hot pixel
    assert M.compare(v, ref)["max_abs"] == 0.0
    assert M.compare(v, ref)["rmse"] == pytest.approx(1.0 / 9)
    v[1:4, 1:4] = 0.5                   # a 3x3 block of real error survives the median
    assert M.compare(v, ref)["max_abs"] == pytest.approx(0.5)


def test_median3x3_matches_brute_force():
    rng = np.random.default_rng(3)
    img = rng.random((7, 6))
    mask = rng.random((7, 6)) > 0.3
    out = M.median3x3(img, mask)
    for y in range(7):
        for x in range(6):
            if not mask[y, x]:
                assert np.isnan(out[y, x])
                continue
            vals = [img[j, i] for j in range(max(0, y - 1), min(7, y + 2))
                    for i in range(max(0, x - 1), min(6, x + 2)) if mask[j, i]]
            assert out[y, x] == pytest.approx(np.median(vals))


def test_empty_mask_gives_nan_and_zero_counts():
    v, ref = _field()
    r = M.compare(v, ref, np.zeros((4, 4), bool))
    assert r["n_mask"] == 0 and r["n_shadow"] == 0
    for k in ("mae_shadow", "mae", "rmse", "max_abs", "pixel_match"):
        assert math.isnan(r[k])


def test_fully_lit_has_no_shadow_pixels():
    v, ref = _field()
    r = M.compare(v, ref)
    assert r["n_shadow"] == 0 and math.isnan(r["mae_shadow"])
    assert r["rmse"] == 0.0 and r["max_abs"] == 0.0 and r["pixel_match"] == 1.0


def test_nan_pixels_leave_the_mask():
    v, ref = _field()
    ref[0, 0] = 0.0
    v[0, 0] = 0.0
    v[1, 1] = np.nan
    ref[2, 2] = np.inf
    r = M.compare(v, ref)
    assert r["n_mask"] == 14
    assert r["n_shadow"] == 1 and r["mae_shadow"] == 0.0
    assert all(np.isfinite(r[k]) for k in ("mae", "rmse", "max_abs", "pixel_match"))


def test_shape_errors():
    with pytest.raises(ValueError):
        M.compare(np.ones((3, 3)), np.ones((3, 4)))
    with pytest.raises(ValueError):
        M.compare(np.ones((3, 3)), np.ones((3, 3)), np.ones((2, 2), bool))
    with pytest.raises(ValueError):
        M.compare(np.ones((3, 3, 3)), np.ones((3, 3, 3)))


def test_ssim_identity_constants_and_symmetry():
    rng = np.random.default_rng(0)
    a = rng.random((32, 32, 3))
    assert M.ssim(a, a) == pytest.approx(1.0)
    assert M.ssim(a, a, window="box") == pytest.approx(1.0)
    # constant images: variances vanish, SSIM is the luminance term (2xy + C1) / (x^2 + y^2 + C1)
    x, y = 0.2, 0.6
    c1 = (0.01 * 1.0) ** 2
    expect = (2 * x * y + c1) / (x * x + y * y + c1)
    assert M.ssim(np.full((20, 20), x), np.full((20, 20), y)) == pytest.approx(expect)
    # RGB goes through Rec. 709 luminance: grey (x, x, x) has luminance x
    assert M.ssim(np.full((20, 20, 3), x), np.full((20, 20), y)) == pytest.approx(expect)
    b = np.clip(a + rng.normal(0, 0.1, a.shape), 0, 1)
    s = M.ssim(a, b)
    assert 0.0 < s < 0.99
    assert M.ssim(b, a) == pytest.approx(s)
    mean, smap = M.ssim(a, b, full=True)
    assert smap.shape == (22, 22) and mean == pytest.approx(s)


def test_flip_optional():
    a = np.random.default_rng(1).random((24, 24, 3)).astype(np.float32)
    if not M.HAVE_FLIP:
        with pytest.raises(ImportError):
            M.flip(a, a)
        return
    assert M.flip(a, a) == pytest.approx(0.0, abs=1e-6)
    b = a.copy()
    b[8:16, 8:16] = 0.0
    assert M.flip(a, b) > 0.01
    assert M.flip(a, b, hdr=False) > 0.01


def test_ssim_shaded_is_one_for_the_same_visibility_and_drops_with_a_wrong_one():
    from penumbra.engine.measure.metrics import ssim_shaded
    rng = np.random.default_rng(0)
    unshadowed = np.full((40, 40, 3), 0.6, np.float32) + rng.random((40, 40, 3), dtype=np.float32) * 0.01
    v = np.ones((40, 40), np.float32)
    v[10:30, 10:30] = 0.2
    assert ssim_shaded(unshadowed * v[..., None], unshadowed, v) > 0.999
    assert ssim_shaded(unshadowed, unshadowed, v) < 0.9


def test_unshadowed_error_leaves_out_grazed_silhouette_pixels():
    """A pixel whose centre is off our surface, beside a covered one, gets a trace of light in Cycles (its
    narrow pixel filter grazes the silhouette: fuzz seed 3033); it is left out given our Depth. A hole in our
    coverage away from any covered pixel still counts."""
    from penumbra.engine.measure.compare import unshadowed_error
    bg = 1.0e10
    cycles = np.zeros((6, 6, 3))
    cycles[1:3, 1:3] = 5.0
    cycles[1, 3] = 0.03                      # grazed: Cycles sees the surface in 0.6 % of its samples
    ours = np.zeros_like(cycles)
    ours[1:3, 1:3] = 5.0
    depth = np.full((6, 6), bg)
    depth[1:3, 1:3] = 4.0
    mask = cycles[..., 0] > 0
    assert unshadowed_error(ours, cycles, mask, depth, bg) == 0.0
    cycles[1, 3] = 3.0                       # more than half its neighbour: only our Depth leaves it out
    assert unshadowed_error(ours, cycles, mask) == pytest.approx(1.0 / 5.0)
    assert unshadowed_error(ours, cycles, mask, depth, bg) == 0.0
    cycles[1, 3] = 0.0
    cycles[3, 3] = 0.03                      # grazed at a corner of our silhouette (fuzz seed 11017)
    assert unshadowed_error(ours, cycles, mask | (cycles[..., 0] > 0), depth, bg) == 0.0
    cycles[3, 3] = 0.0
    cycles[1, 3] = 0.03
    cycles[4, 4] = 5.0                       # a surface we miss entirely, far from our silhouette
    mask = cycles[..., 0] > 0
    assert unshadowed_error(ours, cycles, mask, depth, bg) == pytest.approx(1.0 / 5.0)


def test_unshadowed_error_leaves_out_a_stray_lit_pixel_past_a_hard_light_edge():
    """A pixel just past a hard-edged spot cone that we leave unlit, where Cycles has one lit sample out of
    256 (a stray camera ray: fuzz seed 8020), is left out; a pixel past the edge that Cycles lights at more
    than half its neighbour's value (the edge really lies past that pixel's centre) still counts, as does a
    pixel we leave dark away from anything we light."""
    from penumbra.engine.measure.compare import unshadowed_error
    cycles = np.zeros((6, 6, 3))
    cycles[1:4, 1:3] = 5.4
    ours = cycles.copy()
    cycles[2, 3] = 5.4 / 256.0
    mask = cycles[..., 0] > 0
    assert unshadowed_error(ours, cycles, mask) == 0.0
    cycles[2, 3] = 4.0                       # we end the cone a pixel early
    assert unshadowed_error(ours, cycles, mask) == pytest.approx(1.0 / 7.0)
    cycles[2, 3] = 0.0
    cycles[5, 5] = 0.02                      # a dim pixel we miss, with nothing of ours lit beside it
    mask = cycles[..., 0] > 0
    assert unshadowed_error(ours, cycles, mask) == pytest.approx(1.0 / 7.0)


def test_unshadowed_error_counts_a_pixel_at_most_as_wholly_wrong():
    """A pixel we light where Cycles has a trace of light (the last pixel before a floor crosses a large area
    light's plane: fuzz seeds 1035, 1039) weighs as a pixel we leave dark does, not 500 times more; an image
    lit 30 % too brightly everywhere still shows its 0.3."""
    from penumbra.engine.measure.compare import unshadowed_error
    cycles = np.full((6, 6, 3), 2.0)
    ours = cycles.copy()
    cycles[2, 3] = 2.0 / 500.0
    mask = np.ones((6, 6), bool)
    assert unshadowed_error(ours, cycles, mask) == pytest.approx(1.0 / 36.0)
    ours[2, 3] = 0.0
    cycles[2, 3] = 2.0
    assert unshadowed_error(ours, cycles, mask) == pytest.approx(1.0 / 36.0)
    assert unshadowed_error(cycles * 1.3, cycles, mask) == pytest.approx(0.3)
