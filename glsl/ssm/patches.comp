// SSM's micro-patch list on the GPU (Atty et al. 2006, §3.3): the rows of engine/structures/ssm_maps.py
// patch_list (the reference), in its order (row-major texel order), so the scatter and its FP16 batches
// (appendix A) see exactly what the CPU list gave. The extent arithmetic runs in double precision, as
// numpy's does, so the float32 rows agree to the bit wherever the GPU's double division is correctly rounded.
//
// The map is cut into runs of RUN consecutive texels (flat index j·width + i), one invocation per run:
// PASS 0  farthest receiver depth zr_max of the far receiver map (atomic max: positive floats order as
//         their bits)
// PASS 1  per run: how many patches it keeps and their summed clipped extent area (the work estimate)
// PASS 2  one work group: exclusive scan of the run counts (each run's first row), the total count and the
//         total work, summed in run order (deterministic)
// PASS 3  each run writes its rows from its offset, in texel order
// Only the header (count, work: 16 bytes) is read back, to decide whether the map must be made coarser;
// PASS 3 runs once the size is settled. No shared memory and no barriers outside PASS 2: a software GL
// (llvmpipe) pays for every barrier of every invocation.
#ifndef PASS
#define PASS 1
#endif
#define RUN 32                  // texels per run
#if PASS == 2
#define THREADS 256
#else
#define THREADS 64
#endif
layout(local_size_x = THREADS) in;

struct Run {
    uint count;     // patches kept in this run
    uint offset;    // its first row (PASS 2)
    double work;    // their summed clipped extent area, texels²
};
layout(std430, binding = 0) buffer Scratch {
    uint total;     // patches of the map (PASS 2)
    uint pad;
    double work;    // estimated texel updates of the scatter (PASS 2)
    Run runs[];
};
layout(std430, binding = 1) buffer Far { uint zr_bits; };     // zr_max as float bits; 0: no receiver
struct Patch {
    vec4 rect;      // penumbra extent in texels: x0, y0, x1, y1
    vec4 data;      // texel i, j; depth zo; object index
};
layout(std430, binding = 2) writeonly buffer Patches { Patch patches[]; };

uniform ivec2 u_image_size;     // occluder-map texels
uniform int u_runs;             // runs of the map
uniform sampler2D u_map;        // PASS 0: far receiver map; else the occluder map (depth, object)
uniform dvec2 u_half;           // light half extent (metres, or tan for a sun)
uniform dvec2 u_texel;          // texel size in window units
uniform double u_bias;          // relative depth gap DEPTH_EPSILON
uniform double u_facet_reach;   // sloped facets: how far in front of its patch an edge may lie (ssm_maps.py
                                // facet_reach: metres for a sun, a share of the depth otherwise); 0: flat
uniform int u_ortho;

#if PASS == 2
shared uint s_count[THREADS];
shared double s_work[THREADS];
#endif

bool depth_valid(float z) {
    return z > 0.0 && z < EMPTY_DEPTH;
}

ivec2 texel_at(uint index) {
    return ivec2(int(index % uint(u_image_size.x)), int(index / uint(u_image_size.x)));
}

// patch_list for one texel: its extent rectangle, clipped area and (depth, object); false when it is no
// patch (empty texel, not in front of the farthest receiver, or an empty extent).
bool micro_patch(ivec2 ij, double zr, out dvec4 rect, out double area, out vec2 depth_id) {
    depth_id = texelFetch(u_map, ij, 0).xy;
    if (!depth_valid(depth_id.x)) return false;
    double zo = double(depth_id.x);
    if (!(zo < zr * (1.0LF - u_bias))) return false;       // also every texel when no receiver (zr = 0)
    // §3.3: the extent at the farthest receiver is the patch widened by h·s on each side, s the penumbra
    // spread (of the facet's nearest possible edge); 1e-30 m keeps a patch on the light plane finite, 4× the
    // map clamps it to cover the map.
    precise double z = max(u_ortho == 1 ? zo - u_facet_reach : zo * (1.0LF - u_facet_reach), 1e-30LF);
    precise double s = max(u_ortho == 1 ? zr - z : 1.0LF / z - 1.0LF / zr, 0.0LF);
    precise double gx = min(u_half.x * s / u_texel.x, 4.0LF * double(u_image_size.x));
    precise double gy = min(u_half.y * s / u_texel.y, 4.0LF * double(u_image_size.y));
    dvec2 size = dvec2(u_image_size);
    precise dvec2 lo = clamp(dvec2(ij) - dvec2(gx, gy), dvec2(0.0LF), size);
    precise dvec2 hi = clamp(dvec2(ij + 1) + dvec2(gx, gy), dvec2(0.0LF), size);
    rect = dvec4(lo, hi);
    precise dvec2 side = max(hi - lo, dvec2(0.0LF));
    area = side.x * side.y;
    return area > 0.0LF;
}

void main() {
#if PASS == 2
    // Thread `local` takes a stretch of consecutive runs; thread 0 scans the stretches.
    uint local = gl_LocalInvocationID.x;
    uint chunk = (uint(u_runs) + uint(THREADS) - 1u) / uint(THREADS);
    uint first = local * chunk, last = min(first + chunk, uint(u_runs));
    uint stretch_count = 0u;
    double stretch_work = 0.0LF;
    for (uint r = first; r < last; ++r) {
        stretch_count += runs[r].count;
        stretch_work += runs[r].work;
    }
    s_count[local] = stretch_count;
    s_work[local] = stretch_work;
    barrier();
    if (local == 0u) {
        uint running = 0u;
        double sum = 0.0LF;
        for (uint t = 0u; t < uint(THREADS); ++t) {
            uint c = s_count[t];
            s_count[t] = running;
            running += c;
            sum += s_work[t];
        }
        total = running;
        pad = 0u;
        work = sum;
    }
    barrier();
    uint offset = s_count[local];
    for (uint r = first; r < last; ++r) {
        runs[r].offset = offset;
        offset += runs[r].count;
    }
#else
    uint run = gl_GlobalInvocationID.x;
    if (run >= uint(u_runs)) return;
    uint first = run * uint(RUN), last = min(first + uint(RUN), uint(u_image_size.x * u_image_size.y));
#if PASS == 0
    uint bits = 0u;
    for (uint index = first; index < last; ++index) {
        float z = texelFetch(u_map, texel_at(index), 0).x;
        if (depth_valid(z)) bits = max(bits, floatBitsToUint(z));
    }
    if (bits > 0u) atomicMax(zr_bits, bits);
#else
#if PASS == 3
    uint row = runs[run].offset;
    if (runs[run].count == 0u) return;
#endif
    double zr = double(uintBitsToFloat(zr_bits));
    uint count = 0u;
    double run_work = 0.0LF;
    for (uint index = first; index < last; ++index) {
        ivec2 ij = texel_at(index);
        dvec4 rect;
        double area;
        vec2 depth_id;
        if (!micro_patch(ij, zr, rect, area, depth_id)) continue;
#if PASS == 1
        count += 1u;
        run_work += area;
#else
        patches[row++] = Patch(vec4(rect), vec4(vec2(ij), depth_id));
#endif
    }
#if PASS == 1
    runs[run].count = count;
    runs[run].work = run_work;
#endif
#endif
#endif
}
