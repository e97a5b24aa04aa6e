"""Importance images (Schwarz & Stamminger 2008, §4.2: a budget map from an importance source): an image's grey
value per pixel, 0 … 1, as stored (no colour transform: a mask painted 50 % grey means half importance).
Arrays have row 0 at the image's bottom, as Blender's pixels and the GPU's textures do. No bpy here."""
from __future__ import annotations

import os

import numpy as np

# Rec. 709 luma weights: the grey value of a colour image.
_LUMA = np.array([0.2126, 0.7152, 0.0722])


def grey(pixels: np.ndarray) -> np.ndarray:
    """(H, W) float32 in [0, 1] from (H, W), (H, W, 1), (H, W, 3) or (H, W, 4) pixels (alpha ignored)."""
    a = np.asarray(pixels, np.float64)
    if a.ndim == 3:
        a = a[..., 0] if a.shape[2] < 3 else a[..., :3] @ _LUMA
    if a.ndim != 2 or a.size == 0:
        raise ValueError(f"an importance image needs rows and columns, got shape {np.shape(pixels)}")
    return np.clip(np.nan_to_num(a), 0.0, 1.0).astype(np.float32)


def load_grey(path: str, setting: str) -> np.ndarray:
    """The grey value of an image file (EXR through OpenEXR, other formats through Pillow), row 0 at the
    bottom. A missing or unreadable file is a ValueError naming `setting`."""
    if not os.path.isfile(path):
        raise ValueError(f"Setting '{setting}': no image or file named '{path}'")
    try:
        if path.lower().endswith(".exr"):
            from . import exr
            layers = exr.read(path)     # layer → (H, W, C), row 0 at the bottom already
            return grey(layers.get("Combined", next(iter(layers.values()))))
        from PIL import Image
        with Image.open(path) as im:
            if im.mode in ("I", "I;16", "I;16B"):       # 16-bit grey
                pixels = np.asarray(im.convert("I"), np.float64) / 65535.0
            elif im.mode == "F":
                pixels = np.asarray(im, np.float64)
            else:
                pixels = np.asarray(im.convert("RGB"), np.float64) / 255.0
        return grey(np.flipud(pixels))  # files store the top row first
    except ValueError:
        raise
    except Exception as exc:          # a damaged or unknown format: one line naming the setting
        raise ValueError(f"Setting '{setting}': cannot read '{path}' as an image ({exc})") from None


def bilinear(image: np.ndarray, x, y) -> np.ndarray:
    """`image` (H, W, …) bilinearly sampled at texel coordinates x, y (arrays of one shape; texel centres at
    whole numbers), clamped to the edge texels."""
    h, w = image.shape[:2]
    x, y = np.clip(x, 0.0, w - 1), np.clip(y, 0.0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    extra = (1,) * (image.ndim - 2)
    fx, fy = (x - x0).reshape(x.shape + extra), (y - y0).reshape(y.shape + extra)
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def resample(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A (H, W) image stretched over a frame of `size` = (width, height): (height, width), bilinear from
    pixel centre to pixel centre."""
    h, w = image.shape
    width, height = size
    x = (np.arange(width) + 0.5) * w / width - 0.5
    y = (np.arange(height) + 0.5) * h / height - 0.5
    xx, yy = np.meshgrid(x, y)
    return bilinear(image, xx, yy).astype(np.float32)
