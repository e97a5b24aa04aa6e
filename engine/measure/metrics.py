"""Error metrics between a visibility image and the Cycles reference. numpy only: no bpy, no scipy.

All images are (H, W) float arrays of visibility V in [0, 1] (1 = fully lit, 0 = umbra) plus a boolean
mask of the pixels where the reference is meaningful (the surface receives light at all; see
`engine.measure.reference`). Row order does not matter here as long as all inputs share it.

`compare` is the main entry point. `ssim` and `flip` are optional perceptual metrics on RGB images;
`flip` needs the `flip-evaluator` package and raises ImportError without it (`HAVE_FLIP` tells).
"""
from __future__ import annotations

import math

import numpy as np

try:  # optional: NVIDIA's FLIP (pip install flip-evaluator)
    import flip_evaluator as _flip_evaluator
    HAVE_FLIP = True
except Exception:  # pragma: no cover - depends on the environment
    _flip_evaluator = None
    HAVE_FLIP = False

# Pixels where either V or V_ref is below this count as shadow/penumbra for `mae_shadow`.
SHADOW_LEVEL = 0.99
# Rec. 709 / sRGB luminance weights for linear RGB.
LUMA = np.array([0.2126, 0.7152, 0.0722])

__all__ = ["compare", "median3x3", "ssim", "flip", "luminance", "HAVE_FLIP", "SHADOW_LEVEL"]


def _as_2d(name: str, a) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"{name} must be (H, W), got shape {a.shape}")
    return a


def median3x3(img: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """3x3 median of `img` (H, W). Pixels outside `mask` (and NaNs) take no part in any window, and the
    border is treated the same way (no padding values are invented). Output is NaN where the pixel is
    outside the mask, and otherwise the median of the valid pixels in its 3x3 neighbourhood."""
    img = np.asarray(img, dtype=np.float64)
    if mask is None:
        mask = np.ones(img.shape, dtype=bool)
    valid = np.asarray(mask, dtype=bool) & np.isfinite(img)
    out = np.full(img.shape, np.nan)
    if not valid.any():
        return out
    padded = np.pad(np.where(valid, img, np.nan), 1, mode="constant", constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, (3, 3))  # (H, W, 3, 3), a view
    sel = windows[valid].reshape(-1, 9)  # only pixels whose centre is valid: never an all-NaN window
    out[valid] = np.nanmedian(sel, axis=1)
    return out


def compare(v, v_ref, mask=None, *, shadow_level: float = SHADOW_LEVEL) -> dict:
    """Metrics between a visibility image `v` and the reference `v_ref`, over `mask` (all pixels if None).

    Returns a dict of floats/ints:
      mae_shadow  mean |V - V_ref| over masked pixels where V or V_ref < `shadow_level` (shadow + penumbra,
                  the normalisation of Atty et al. 2006, so large lit areas do not dilute the error)
      mae         mean |V - V_ref| over all masked pixels
      rmse        root mean square of V - V_ref over masked pixels
      max_abs     maximum over masked pixels of the 3x3 median of |V - V_ref| (robust to lone outliers,
                  e.g. single noisy reference pixels or edge aliasing)
      pixel_match share of masked pixels where V and V_ref fall on the same side of 0.5
      n_mask      number of masked pixels (non-finite values in either image are dropped from the mask)
      n_shadow    number of pixels `mae_shadow` was taken over
    A metric whose pixel set is empty is NaN (with its count 0); nothing raises for empty masks.
    """
    v = _as_2d("v", v)
    v_ref = _as_2d("v_ref", v_ref)
    if v.shape != v_ref.shape:
        raise ValueError(f"shape mismatch: v {v.shape} vs v_ref {v_ref.shape}")
    m = np.ones(v.shape, bool) if mask is None else np.asarray(mask, dtype=bool)
    if m.shape != v.shape:
        raise ValueError(f"mask shape {m.shape} does not match image shape {v.shape}")
    m = m & np.isfinite(v) & np.isfinite(v_ref)

    n_mask = int(m.sum())
    shadow = m & ((v < shadow_level) | (v_ref < shadow_level))
    n_shadow = int(shadow.sum())
    nan = float("nan")
    out = dict(mae_shadow=nan, mae=nan, rmse=nan, max_abs=nan, pixel_match=nan,
               n_mask=n_mask, n_shadow=n_shadow)
    if n_mask == 0:
        return out

    diff = np.abs(v - v_ref)
    d = diff[m]
    out["mae"] = float(d.mean())
    out["rmse"] = float(math.sqrt(float(np.mean(d * d))))
    out["max_abs"] = float(np.nanmax(median3x3(diff, m)[m]))
    out["pixel_match"] = float(np.mean((v[m] < 0.5) == (v_ref[m] < 0.5)))
    if n_shadow:
        out["mae_shadow"] = float(diff[shadow].mean())
    return out


def ssim_shaded(combined: np.ndarray, unshadowed: np.ndarray, v_ref: np.ndarray) -> float:
    """Perceptual check on the image a person sees: SSIM between our Combined pass and the same shading
    with the reference visibility instead of ours (Cycles' V_ref applied to our Unshadowed pass)."""
    target = unshadowed[..., :3] * np.asarray(v_ref, np.float32)[..., None]
    ours = combined[..., :3]
    peak = float(max(np.percentile(luminance(target), 99.5), 1e-6))
    return float(ssim(np.clip(ours / peak, 0, 1), np.clip(target / peak, 0, 1)))


def luminance(img) -> np.ndarray:
    """Rec. 709 luminance of a linear RGB(A) image (H, W, 3|4); (H, W) images pass through."""
    img = np.asarray(img, dtype=np.float64)
    if img.ndim == 2:
        return img
    if img.ndim == 3 and img.shape[2] in (3, 4):
        return img[..., :3] @ LUMA
    if img.ndim == 3 and img.shape[2] == 1:
        return img[..., 0]
    raise ValueError(f"expected (H, W) or (H, W, 3|4), got {img.shape}")


def _gaussian_kernel(size: int, sigma: float) -> np.ndarray:
    x = np.arange(size, dtype=np.float64) - (size - 1) / 2.0
    k = np.exp(-0.5 * (x / sigma) ** 2)
    return k / k.sum()


def _filter_valid(img: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Separable 'valid' correlation of a 2-D image with the 1-D kernel `k` along both axes."""
    n = len(k)
    h, w = img.shape
    rows = sum(k[i] * img[i:h - n + 1 + i, :] for i in range(n))
    return sum(k[i] * rows[:, i:w - n + 1 + i] for i in range(n))


def ssim(a, b, *, data_range: float = 1.0, window: str = "gaussian", full: bool = False):
    """Structural similarity (Wang et al. 2004) between the luminances of two images.

    `a`, `b`: (H, W) or linear RGB (H, W, 3|4). `window`: "gaussian" (11x11, sigma 1.5, the paper's
    choice) or "box" (8x8 uniform). Constants K1 = 0.01, K2 = 0.03 with dynamic range `data_range`.
    Statistics use the 'valid' region only (no padding). Returns the mean SSIM, or (mean, map) when
    `full`. Images smaller than the window are compared with one window covering the whole image.
    """
    x = luminance(a)
    y = luminance(b)
    if x.shape != y.shape:
        raise ValueError(f"shape mismatch: {x.shape} vs {y.shape}")
    if window not in ("gaussian", "box"):
        raise ValueError("window must be 'gaussian' or 'box'")
    size = min(11 if window == "gaussian" else 8, *x.shape)
    k = _gaussian_kernel(size, 1.5) if window == "gaussian" else np.full(size, 1.0 / size)

    c1 = (0.01 * data_range) ** 2
    c2 = (0.03 * data_range) ** 2
    mx = _filter_valid(x, k)
    my = _filter_valid(y, k)
    sxx = _filter_valid(x * x, k) - mx * mx
    syy = _filter_valid(y * y, k) - my * my
    sxy = _filter_valid(x * y, k) - mx * my
    smap = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    mean = float(smap.mean())
    return (mean, smap) if full else mean


def flip(reference, test, *, hdr: bool = True, ppd: float | None = None, full: bool = False):
    """Mean NVIDIA FLIP error (0 = identical) between two RGB images (H, W, 3), reference first.

    `hdr=True` treats the inputs as linear HDR (non-negative); `hdr=False` as LDR sRGB in [0, 1].
    Needs the optional `flip-evaluator` package; raises ImportError when it is not installed.
    Returns the mean error, or (mean, error_map) when `full`.
    """
    if not HAVE_FLIP:
        raise ImportError("flip() needs the optional package flip-evaluator (pip install flip-evaluator)")
    ref = np.ascontiguousarray(np.asarray(reference, dtype=np.float32))
    tst = np.ascontiguousarray(np.asarray(test, dtype=np.float32))
    if ref.ndim == 2:
        ref = np.repeat(ref[..., None], 3, axis=2)
    if tst.ndim == 2:
        tst = np.repeat(tst[..., None], 3, axis=2)
    ref, tst = ref[..., :3], tst[..., :3]
    if hdr:
        ref, tst = np.maximum(ref, 0.0), np.maximum(tst, 0.0)
    else:
        ref, tst = np.clip(ref, 0.0, 1.0), np.clip(tst, 0.0, 1.0)
    params = {} if ppd is None else {"ppd": float(ppd)}
    err_map, mean, _ = _flip_evaluator.evaluate(ref, tst, "HDR" if hdr else "LDR",
                                                applyMagma=False, parameters=params)
    return (float(mean), np.asarray(err_map)) if full else float(mean)
