// Which covered pixels this light reaches, reduced on the GPU to what the pipeline needs on the CPU: their
// count and the world-space box around them and their lifted shadow-ray starts (engine/render/pipeline.py
// _lit_bounds). A few bytes come back instead of the whole irradiance image. With u_count_hidden it also
// counts the lit pixels that see the light's centre at or below their horizon, by both normals: rim views are
// built only when there are such pixels (engine/core/lightview.py sun_rim_faces and local_rim_lights, which
// make the exact test on the CPU), so the normals are read back only then. The count errs on the side of more
// (a looser threshold). For a local light it also keeps the distance from its centre to the nearest lit pixel
// (REFERENCE's choice of a sphere light's sample region, averaged._fills_ball).
// Floats are compared as order-preserving unsigned integers (sign bit flipped for positives, all bits for
// negatives), so atomicMin/atomicMax on uints give the exact float32 minimum and maximum.
#include "common/pixel.glsl"

layout(std430, binding = 0) buffer LitBounds {
    uint count;
    uint lo[3];     // encoded minimum x, y, z
    uint hi[3];     // encoded maximum x, y, z
    uint hidden;    // lit pixels with the light's axis point below their horizon (u_count_hidden only)
    uint nearest;   // encoded distance from a local light's centre to the nearest lit pixel
} result;

uniform int u_count_hidden;
uniform vec4 u_light_centre;    // w = 0: world unit vector towards a sun's centre; w = 1: a local light's position

shared uint s_count;
shared uint s_lo[3];
shared uint s_hi[3];
shared uint s_hidden;
shared uint s_nearest;

uint ordered(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : (u | 0x80000000u);
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (gl_LocalInvocationIndex == 0u) {
        s_count = 0u;
        s_hidden = 0u;
        s_nearest = 0xFFFFFFFFu;
        for (int i = 0; i < 3; ++i) { s_lo[i] = 0xFFFFFFFFu; s_hi[i] = 0u; }
    }
    barrier();
    if (pixel_in_image(px) && pixel_lit(px)) {
        vec3 p = texelFetch(g_position, px, 0).xyz;
        // The box also holds where the pixel's shadow rays may leave from: anywhere up to the whole terminator
        // lift along the shading normal (common/light_view.glsl make_lit_receiver). A lifted start outside the
        // view's window counted as lit: fuzz 29243, a smooth cylinder's 32-gon cap lit from behind its plane,
        // whose starts lie 0.2 m off the cap, beyond the window, where Cycles finds the ground in the way.
        vec3 lifted = p + texelFetch(g_normal, px, 0).xyz * texelFetch(g_geometric, px, 0).w;
        atomicAdd(s_count, 1u);
        for (int i = 0; i < 3; ++i) {
            atomicMin(s_lo[i], ordered(min(p[i], lifted[i])));
            atomicMax(s_hi[i], ordered(max(p[i], lifted[i])));
        }
        vec3 to_centre = u_light_centre.w == 0.0 ? u_light_centre.xyz : u_light_centre.xyz - p;
        if (u_light_centre.w != 0.0)
            atomicMin(s_nearest, ordered(length(to_centre)));
        if (u_count_hidden != 0) {
            to_centre /= max(length(to_centre), 1e-30);
            if (dot(texelFetch(g_geometric, px, 0).xyz, to_centre) <= 1e-5
                    && dot(texelFetch(g_normal, px, 0).xyz, to_centre) <= 1e-5)
                atomicAdd(s_hidden, 1u);
        }
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u && s_count > 0u) {    // one global update per work group
        atomicAdd(result.count, s_count);
        atomicAdd(result.hidden, s_hidden);
        atomicMin(result.nearest, s_nearest);
        for (int i = 0; i < 3; ++i) {
            atomicMin(result.lo[i], s_lo[i]);
            atomicMax(result.hi[i], s_hi[i]);
        }
    }
}
