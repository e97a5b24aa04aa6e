"""Multilayer EXR and PNG files, written atomically (engine/files.py)."""
from __future__ import annotations

import zlib
import struct

import numpy as np

from .files import atomic_write
from .passes import BASE_PASSES, DEBUG_PASSES

_CHANNELS = {name: chan_id for name, _, chan_id, _ in BASE_PASSES + DEBUG_PASSES}


def write(path: str, passes: dict, metadata: dict | None = None) -> None:
    """Passes (name → (H, W, C) float32, row 0 at the bottom) as one multilayer EXR, channels named
    `Pass.R`, `Depth.Z`, `Visibility.X` like Blender's own multilayer files."""
    import OpenEXR
    channels = {}
    for name, array in passes.items():
        ids = _CHANNELS.get(name, "RGBA"[: array.shape[-1]])
        top_down = np.ascontiguousarray(np.flipud(array).astype(np.float32))
        for i, cid in enumerate(ids):
            channels[f"{name}.{cid}"] = np.ascontiguousarray(top_down[..., i])
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    for key, value in (metadata or {}).items():
        header[key] = str(value)

    def _write(tmp):
        with OpenEXR.File(header, channels) as f:
            f.write(tmp)
    atomic_write(path, _write)


def read(path: str) -> dict:
    """Inverse of `write` (also reads Blender's multi-part files): name → (H, W, C), row 0 at the bottom."""
    import OpenEXR
    out: dict = {}
    with OpenEXR.File(path, separate_channels=True) as f:
        for part in f.parts:
            part_layer = (part.name() or "Combined").rpartition(".")[2]
            for cname, channel in part.channels.items():
                # "ViewLayer.Combined.R" (Blender), "Combined.R" (ours) or a bare "R" in a named part.
                pieces = cname.split(".")
                layer = pieces[-2] if len(pieces) > 1 else part_layer
                out.setdefault(layer, {})[pieces[-1]] = np.flipud(channel.pixels.astype(np.float32))
    result = {}
    for layer, chans in out.items():
        order = _CHANNELS.get(layer) or "".join(c for c in "RGBAXYZ" if c in chans) or "".join(chans)
        result[layer] = np.stack([chans[c] for c in order if c in chans], axis=-1)
    return result


def to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear RGB → 8-bit sRGB (the standard view transform), row 0 at the top for image files."""
    x = np.clip(np.nan_to_num(linear[..., :3]), 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.flipud((s * 255.0 + 0.5).astype(np.uint8))


def write_png(path: str, rgb8: np.ndarray) -> None:
    """A plain RGB PNG (no dependencies). `rgb8`: (H, W, 3) uint8, row 0 at the top."""
    h, w = rgb8.shape[:2]
    raw = b"".join(b"\0" + rgb8[y].tobytes() for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) + \
        chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")

    def _write(tmp):
        with open(tmp, "wb") as f:
            f.write(png)
    atomic_write(path, _write)
