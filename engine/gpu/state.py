"""GL state scopes: a block sets the fixed-function state it needs and leaves the defaults the rest of the
engine assumes (depth test "<", no blending) behind it, whatever happens inside."""
from __future__ import annotations

from contextlib import contextmanager


@contextmanager
def gl_state(ctx, *, depth_test: bool, cull: bool = False, blend: bool = False, depth_func: str = "<",
             additive: bool = False, minimum: bool = False):
    """Depth test on/off (with `depth_func`), face culling, and blending (`additive`: ONE, ONE, FUNC_ADD;
    `minimum`: MIN, the nearest value without a depth buffer). On exit blending is off, its equation FUNC_ADD
    and the depth function "<" again."""
    (ctx.enable if depth_test else ctx.disable)(ctx.DEPTH_TEST)
    (ctx.enable if cull else ctx.disable)(ctx.CULL_FACE)
    if blend or additive or minimum:
        ctx.enable(ctx.BLEND)
        if additive or minimum:
            ctx.blend_func = ctx.ONE, ctx.ONE
            ctx.blend_equation = ctx.MIN if minimum else ctx.FUNC_ADD
    else:
        ctx.disable(ctx.BLEND)
    ctx.depth_func = depth_func
    try:
        yield ctx
    finally:
        ctx.disable(ctx.BLEND)
        ctx.blend_equation = ctx.FUNC_ADD
        ctx.depth_func = "<"
