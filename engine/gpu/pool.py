"""GPU resources kept between frames on one context, so a redraw of the same view allocates nothing.

Frames take textures, depth textures and storage buffers from the pool and give them back when they end;
framebuffers are cached by their attachments and live as long as those do. Sizes are exact, not rounded
up: techniques read a texture's own extent (Frame.read, textureSize in the shaders), so a larger texture
than asked for would change what they compute. Free objects a few frames have not asked for are released
(the viewport alternates a coarse and a full size; a resized window or another scene moves on).

One pool per GpuWorker (its `cache`), used only on the GPU thread.
"""
from __future__ import annotations

from collections import Counter

KEEP_FRAMES = 4             # free objects unused for this many frames are released


class ResourcePool:
    def __init__(self, ctx):
        self.ctx = ctx
        self._free: dict[tuple, list] = {}         # key → [(object, frame it was last used), …]
        self._key: dict[int, tuple] = {}            # id(object) → its key, for objects taken out
        self._framebuffers: dict[tuple, object] = {}  # attachment glo ids → framebuffer
        self._clear_fbos: dict[int, object] = {}    # texture glo → framebuffer that clears it
        self.frame = 0
        self.created: Counter = Counter()           # kind → objects created (tests read it)

    # ---- taking and giving back --------------------------------------------------------------------------
    def _take(self, key: tuple, make):
        free = self._free.get(key)
        if free:
            obj = free.pop()[0]
        else:
            obj = make()
            self.created[key[0]] += 1
        self._key[id(obj)] = key
        return obj

    def pooled(self, obj) -> bool:
        return id(obj) in self._key

    def give_back(self, obj) -> None:
        key = self._key.pop(id(obj))
        self._free.setdefault(key, []).append((obj, self.frame))

    def texture(self, size, components: int, dtype: str = "f4"):
        """A texture of exactly this size and format, zero-filled (as a fresh one reads on every driver
        here; pooled ones are cleared on the GPU), GL_NEAREST filtering."""
        key = ("texture", tuple(size), components, dtype)
        fresh = not self._free.get(key)
        tex = self._take(key, lambda: self.ctx.texture(size, components, dtype=dtype))
        tex.filter = (0x2600, 0x2600)   # GL_NEAREST: techniques fetch texels themselves
        if fresh:                       # its clearing framebuffer too, so that reuse allocates nothing
            self._clear_fbos[tex.glo] = self.ctx.framebuffer(color_attachments=[tex])
        else:
            self._clear_fbos[tex.glo].clear(0.0, 0.0, 0.0, 0.0)
        return tex

    def texture_array(self, size, components: int, dtype: str = "f4"):
        """A texture array (width, height, layers), GL_NEAREST; contents undefined, as a fresh one's."""
        key = ("texture_array", tuple(size), components, dtype)
        tex = self._take(key, lambda: self.ctx.texture_array(size, components, dtype=dtype))
        tex.filter = (0x2600, 0x2600)
        return tex

    def depth_texture(self, size, samples: int = 0):
        """A depth texture (multisampled with `samples`); its contents are undefined (every user clears it
        with its framebuffer)."""
        return self._take(("depth", tuple(size), samples), lambda: self.ctx.depth_texture(size, samples=samples))

    def multisample_texture(self, size, components: int, samples: int, dtype: str = "f4"):
        """A multisampled colour texture; contents undefined (the G-buffer's framebuffer clears it)."""
        key = ("texture_ms", tuple(size), components, samples, dtype)
        return self._take(key, lambda: self.ctx.texture(size, components, samples=samples, dtype=dtype))

    def reserved_buffer(self, nbytes: int):
        """A storage buffer of `nbytes`, contents undefined (its user writes what it reads)."""
        return self._take(("buffer", nbytes), lambda: self.ctx.buffer(reserve=nbytes))

    def buffer(self, data: bytes):
        """A storage buffer holding `data` (reused when one of the same byte size is free)."""
        key = ("buffer", len(data))
        fresh = not self._free.get(key)
        buf = self._take(key, lambda: self.ctx.buffer(data))
        if not fresh:
            buf.write(data)
        return buf

    def framebuffer(self, color_attachments, depth_attachment=None):
        """The framebuffer of these attachments (all from this pool), made once while they live."""
        key = tuple(t.glo for t in color_attachments) + ((-1, depth_attachment.glo) if depth_attachment
                                                        else ())
        fbo = self._framebuffers.get(key)
        if fbo is None:
            fbo = self._framebuffers[key] = self.ctx.framebuffer(color_attachments=list(color_attachments),
                                                                 depth_attachment=depth_attachment)
            self.created["framebuffer"] += 1
        return fbo

    # ---- housekeeping ------------------------------------------------------------------------------------
    def end_frame(self) -> None:
        """Release free objects no frame has asked for in KEEP_FRAMES frames."""
        self.frame += 1
        for key, free in list(self._free.items()):
            keep = [(obj, used) for obj, used in free if self.frame - used <= KEEP_FRAMES]
            for obj, used in free:
                if self.frame - used > KEEP_FRAMES:
                    self._release(obj, key[0])
            if keep:
                self._free[key] = keep
            else:
                del self._free[key]

    def _release(self, obj, kind: str) -> None:
        glo = obj.glo
        if kind == "buffer":                # buffer names are not texture names: no framebuffer has it
            obj.release()
            return
        for key in [k for k in self._framebuffers if glo in k]:
            self._framebuffers.pop(key).release()
        clear = self._clear_fbos.pop(glo, None)
        if clear is not None:
            clear.release()
        obj.release()


def pool_of(worker) -> ResourcePool:
    """The worker's pool (created on first use)."""
    pool = worker.cache.get("__resource_pool__")
    if pool is None:
        pool = worker.cache["__resource_pool__"] = ResourcePool(worker.ctx)
    return pool
