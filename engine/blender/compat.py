"""What differs between the Blender versions the manifest allows (4.2 and newer), decided by looking at the
running Blender's API rather than its version number, plus the small scene-settings helpers that every
measurement and image writer shares (a recorder that undoes changes, the output format, the view-transformed
PNG)."""
from __future__ import annotations

import os
import tempfile

import numpy as np

from ..core.files import atomic_write


class SettingsRecorder:
    """Records attribute changes so they can be undone in reverse order, even after an error."""

    def __init__(self):
        self._undo: list[tuple[object, str, object]] = []

    def set(self, obj, attr: str, value):
        old = getattr(obj, attr)
        if isinstance(old, (list, tuple)) or hasattr(old, "to_tuple"):
            old = tuple(old)
        self._undo.append((obj, attr, old))
        setattr(obj, attr, value)

    def restore(self):
        errors = []
        for obj, attr, old in reversed(self._undo):
            try:
                setattr(obj, attr, old)
            except Exception as exc:  # keep restoring the rest
                errors.append(f"{attr}: {exc}")
        self._undo.clear()
        if errors:
            raise RuntimeError("could not restore scene settings: " + "; ".join(errors))


def set_file_format(st: SettingsRecorder, image_settings, file_format: str) -> None:
    """Set an output format through `st`. Blender 5.0 split the format list by `media_type` (a multilayer
    EXR is only offered once media_type is MULTI_LAYER_IMAGE); 4.2–4.5 have no media_type at all. The
    media type is set first, so undoing in reverse restores the format before its media type, the order
    Blender needs when going back."""
    if hasattr(image_settings, "media_type"):
        st.set(image_settings, "media_type",
               "MULTI_LAYER_IMAGE" if file_format == "OPEN_EXR_MULTILAYER" else "IMAGE")
    st.set(image_settings, "file_format", file_format)


def engine_ids(scene=None) -> set[str]:
    """Render engine identifiers the running Blender offers."""
    import bpy
    scene = scene or bpy.context.scene
    return {item.identifier for item in scene.render.bl_rna.properties["engine"].enum_items}


def eevee_engine_id(available: set[str] | None = None) -> str:
    """EEVEE's identifier: 4.2–4.5 call the new EEVEE `BLENDER_EEVEE_NEXT`, 5.0 renamed it `BLENDER_EEVEE`."""
    available = engine_ids() if available is None else available
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in available else "BLENDER_EEVEE"


def _save_display_png(path: str, rgba: np.ndarray, scene) -> None:
    """Linear scene-referred RGBA (H, W, 3|4), row 0 at the bottom, to an 8-bit RGB PNG at `path` through
    Blender's own image writer with `scene`'s colour management (view transform such as AgX or Filmic,
    look, exposure, gamma, display device, dither): the same pixels as a PNG Blender renders itself."""
    import bpy
    h, w = rgba.shape[:2]
    pixels = np.ones((h, w, 4), np.float32)
    pixels[..., :3] = np.nan_to_num(rgba[..., :3])
    image = bpy.data.images.new(".penumbra_display", w, h, float_buffer=True, alpha=False)
    st = SettingsRecorder()
    try:
        image.pixels.foreach_set(pixels.ravel())
        img_settings = scene.render.image_settings
        set_file_format(st, img_settings, "PNG")
        st.set(img_settings, "color_mode", "RGB")
        st.set(img_settings, "color_depth", "8")
        image.save_render(path, scene=scene)
    finally:
        st.restore()
        bpy.data.images.remove(image)


def write_display_png(path: str, rgba: np.ndarray, scene) -> None:
    """`_save_display_png`, written atomically (nothing partial is left at `path` on error)."""
    atomic_write(path, lambda tmp: _save_display_png(tmp, rgba, scene))


def display_rgb8(rgba: np.ndarray, scene) -> np.ndarray:
    """(H, W, 3) uint8 display values of linear `rgba` under `scene`'s view transform, row 0 at the top (as
    in an image file), read back from Blender's own PNG (a byte image's pixels are its stored values/255)."""
    import bpy
    fd, tmp = tempfile.mkstemp(prefix=".penumbra-display-", suffix=".png")
    os.close(fd)
    try:
        _save_display_png(tmp, rgba, scene)
        image = bpy.data.images.load(tmp)
        try:
            w, h = image.size
            px = np.empty(w * h * image.channels, np.float32)
            image.pixels.foreach_get(px)
        finally:
            bpy.data.images.remove(image)
        return np.flipud(px.reshape(h, w, -1)[..., :3] * 255.0 + 0.5).astype(np.uint8)
    finally:
        os.unlink(tmp)
