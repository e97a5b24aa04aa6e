"""The Blender RenderEngine "PENUMBRA": final renders through the GPU pipeline, passes written from the one
generator in engine/passes.py."""
from __future__ import annotations

import bpy

from ..core import passes
from ..render import pipeline
from ..gpu.context import Cancelled, GpuError
from ..gpu.programs import ShaderError
from .extract import extract


def _settings(scene):
    from .settings_bridge import settings_from_scene
    return settings_from_scene(scene)


def format_timings(timings: dict) -> str:
    return " | ".join(f"{name} {ms:.1f} ms" for name, ms in timings.items())


class PenumbraRenderEngine(bpy.types.RenderEngine):
    bl_idname = "PENUMBRA"
    bl_label = "Penumbra"
    bl_use_preview = False
    bl_use_postprocess = True

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._viewport = None               # engine.viewport.ViewportSession, created on first view_update
        self._texture = None                # (frame, pass name, gpu.types.GPUTexture) on screen

    def __del__(self):
        viewport = getattr(self, "_viewport", None)
        if viewport is not None:
            viewport.free()

    def update_render_passes(self, scene=None, renderlayer=None):
        for name, channels, chan_id, kind in passes.render_passes(_settings(scene)):
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)

    def render(self, depsgraph):
        scene = depsgraph.scene
        settings = _settings(scene)
        self.update_stats("", "Penumbra: reading scene")
        try:
            settings.validate()
            snap = extract(depsgraph, scene, settings=settings)
        except ValueError as exc:           # bad input: a message naming the scene/object/setting
            self._fail(str(exc))
            return
        for name, channels, chan_id, _ in passes.render_passes(settings):
            if name != "Combined":
                self.add_pass(name, channels, chan_id)

        def on_progress(fraction, message):
            self.update_progress(fraction)
            if message:
                self.update_stats("", f"Penumbra {settings.technique}: {message}")

        try:
            result = pipeline.render(snap, settings, on_progress=on_progress, should_stop=self.test_break)
        except Cancelled:
            return
        except ValueError as exc:           # e.g. an image larger than the GPU can hold (gpu/frame.py)
            self._fail(str(exc))
            return
        except (GpuError, ShaderError, RuntimeError) as exc:
            self._fail(f"Penumbra: GPU pipeline failed: {exc}")
            return
        for message in result.warnings:
            self.report({"WARNING"}, message)
        self._write(result, snap.camera.width, snap.camera.height)
        self.update_stats("", f"Penumbra {settings.technique}: {result.total_ms:.0f} ms | "
                              f"{format_timings(result.timings)}")

    def _write(self, result, width, height):
        render_result = self.begin_result(0, 0, width, height)
        layer = render_result.layers[0]
        for name, array in result.passes.items():
            target = layer.passes.find_by_name(name, "")     # "": the render's only view
            if target is not None:
                target.rect.foreach_set(array.reshape(-1))
        self.end_result(render_result)

    # ---- interactive viewport -------------------------------------------------------------------------
    def view_update(self, context, depsgraph):
        """Scene changed: re-read only what the depsgraph reports (the first call reads everything)."""
        from .viewport_sync import BlenderViewport
        try:
            if self._viewport is None:
                self._viewport = BlenderViewport()
                self._viewport.sync(depsgraph)
            else:
                self._viewport.sync(depsgraph, depsgraph.updates)
        except (GpuError, ShaderError, RuntimeError, ValueError) as exc:
            self.report({"ERROR"}, f"Penumbra viewport: {exc}")

    def view_draw(self, context, depsgraph):
        """Draw the newest finished frame; ask for a new one when the view changed. Never waits for the GPU."""
        import numpy as np
        from .settings_bridge import viewport_settings
        from ..core.snapshot import Camera
        session = self._viewport
        if session is None:
            return
        scene, region, rv3d = depsgraph.scene, context.region, context.region_data
        camera = Camera("Viewport", np.array(rv3d.view_matrix, np.float64),
                        np.array(rv3d.window_matrix, np.float64), region.width, region.height,
                        is_ortho=not rv3d.is_perspective)
        props = scene.penumbra
        try:
            session.request(camera, viewport_settings(scene), coarse_map=props.viewport_coarse_map_size,
                            coarse_scale=props.viewport_coarse_scale)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return
        if session.error:
            self.report({"ERROR"}, f"Penumbra viewport: {session.error}")
            session.error = None
        frame = session.latest
        if frame is not None:
            if self._texture is None or self._texture[:2] != (frame, props.viewport_pass):
                self._texture = (frame, props.viewport_pass, _frame_texture(frame, props.viewport_pass))
            _draw_texture(self, scene, self._texture[2], region.width, region.height)
            self.update_stats("", f"Penumbra {'coarse' if frame.coarse else 'refined'} frame "
                                  f"{frame.ms:.0f} ms")
        if session.busy():
            _redraw_when_done(self, session)

    def _fail(self, message: str):
        self.report({"ERROR"}, message)
        self.error_set(message)


def _frame_texture(frame, pass_name):
    """The frame's pass as a GPU texture. Called from view_draw only (the gpu module refuses to work at
    import, register or render time), once per new frame."""
    import gpu
    import numpy as np
    data = frame.passes.get(pass_name, frame.passes["Combined"])
    rgba = np.ones((frame.height, frame.width, 4), np.float32)
    rgba[..., :3] = data[..., :3] if data.shape[-1] >= 3 else data[..., :1]
    return gpu.types.GPUTexture((frame.width, frame.height), format="RGBA16F",
                                data=gpu.types.Buffer("FLOAT", rgba.size, rgba.ravel()))


def _draw_texture(engine, scene, texture, width, height):
    """Draw through Blender's display-space shader, so colour management matches Cycles' viewport."""
    import gpu
    from gpu_extras.presets import draw_texture_2d
    gpu.state.blend_set("ALPHA_PREMULT")
    engine.bind_display_space_shader(scene)
    draw_texture_2d(texture, (0, 0), width, height)
    engine.unbind_display_space_shader()
    gpu.state.blend_set("NONE")


def _redraw_when_done(engine, session):
    """Poll from Blender's main thread (a timer) and redraw once the newest frame is in."""
    import weakref
    ref = weakref.ref(engine)
    shown = session.latest

    def poll():
        target = ref()
        if target is None:
            return None
        if session.latest is not shown:
            try:
                target.tag_redraw()
            except ReferenceError:
                return None
            return None
        return 0.02
    bpy.app.timers.register(poll, first_interval=0.02)


def register():
    bpy.utils.register_class(PenumbraRenderEngine)


def unregister():
    bpy.utils.unregister_class(PenumbraRenderEngine)
