// SSM's micro-patch list on the GPU (Atty et al. 2006, §3.3): one invocation per occluder-map texel, the
// same rows as engine/structures/ssm_maps.py patch_list (the reference), in the same order (row-major
// texel order), so the scatter and its FP16 batches (appendix A) see exactly what the CPU list gave.
// The extent arithmetic runs in double precision, as numpy's does, so the float32 rows agree to the bit
// wherever the GPU's double division is correctly rounded.
//
// PASS 0  farthest receiver depth zr_max of the far receiver map (atomic max; positive floats order as
//         their bits)
// PASS 1  per work group of GROUP texels: how many patches it keeps and their summed extent area (work)
// PASS 2  one work group: exclusive scan of the group counts (each group's first row), the total count
//         and the total work (summed in group order: deterministic)
// PASS 3  each group writes its rows from its offset, in texel order (a shared-memory scan of the flags)
// Only the header (count, work: 16 bytes) is read back, to decide whether the map must be made coarser;
// PASS 3 runs once the size is settled.
#ifndef PASS
#define PASS 1
#endif
#define GROUP 256
layout(local_size_x = GROUP) in;

struct Group {
    uint count;     // patches kept in this group
    uint offset;    // its first row (PASS 2)
    double work;    // their summed clipped extent area, texels²
};
layout(std430, binding = 0) buffer Scratch {
    uint total;     // patches of the map (PASS 2)
    uint pad;
    double work;    // estimated texel updates of the scatter (PASS 2)
    Group groups[];
};
layout(std430, binding = 1) buffer Far { uint zr_bits; };     // zr_max as float bits; 0: no receiver
struct Patch {
    vec4 rect;      // penumbra extent in texels: x0, y0, x1, y1
    vec4 data;      // texel i, j; depth zo; object index
};
layout(std430, binding = 2) writeonly buffer Patches { Patch patches[]; };

uniform ivec2 u_image_size;     // occluder-map texels
uniform int u_groups;           // work groups of PASS 1 and 3
uniform sampler2D u_map;        // PASS 0: far receiver map; else the occluder map (depth, object)
uniform dvec2 u_half;           // light half extent (metres, or tan for a sun)
uniform dvec2 u_texel;          // texel size in window units
uniform double u_bias;          // relative depth gap DEPTH_EPSILON
uniform int u_ortho;

shared uint s_count;
shared double s_work[GROUP];
shared uint s_scan[GROUP];

bool depth_valid(float z) {
    return z > 0.0 && z < EMPTY_DEPTH;
}

// This invocation's texel, or false past the map's last texel.
bool texel_of(out ivec2 ij) {
    uint index = gl_WorkGroupID.x * uint(GROUP) + gl_LocalInvocationID.x;
    ij = ivec2(int(index % uint(u_image_size.x)), int(index / uint(u_image_size.x)));
    return index < uint(u_image_size.x * u_image_size.y);
}

// patch_list for one texel: its extent rectangle, clipped area and (depth, object); false when it is no
// patch (empty texel, not in front of the farthest receiver, or an empty extent).
bool micro_patch(ivec2 ij, out dvec4 rect, out double area, out vec2 depth_id) {
    depth_id = texelFetch(u_map, ij, 0).xy;
    if (!depth_valid(depth_id.x)) return false;
    double zo = double(depth_id.x);
    double zr = double(uintBitsToFloat(zr_bits));
    if (!(zo < zr * (1.0LF - u_bias))) return false;       // also every texel when no receiver (zr = 0)
    // §3.3: the extent at the farthest receiver is the patch widened by h·s on each side, s the penumbra
    // spread; 1e-30 m keeps a patch on the light plane finite, 4× the map clamps it to cover the map.
    precise double z = max(zo, 1e-30LF);
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
    uint local = gl_LocalInvocationID.x;
#if PASS == 0
    if (local == 0u) s_count = 0u;      // here: the group's largest depth, as bits
    barrier();
    ivec2 ij;
    if (texel_of(ij)) {
        float z = texelFetch(u_map, ij, 0).x;
        if (depth_valid(z)) atomicMax(s_count, floatBitsToUint(z));
    }
    barrier();
    if (local == 0u && s_count > 0u) atomicMax(zr_bits, s_count);
#elif PASS == 1
    ivec2 ij;
    dvec4 rect;
    double area = 0.0LF;
    vec2 depth_id;
    bool kept = texel_of(ij) && micro_patch(ij, rect, area, depth_id);
    if (local == 0u) s_count = 0u;
    s_work[local] = kept ? area : 0.0LF;
    barrier();
    if (kept) atomicAdd(s_count, 1u);
    for (uint step = uint(GROUP) / 2u; step > 0u; step >>= 1) {     // tree sum: the same order every run
        if (local < step) s_work[local] += s_work[local + step];
        barrier();
    }
    if (local == 0u) {
        groups[gl_WorkGroupID.x].count = s_count;
        groups[gl_WorkGroupID.x].work = s_work[0];
    }
#elif PASS == 2
    // Thread `local` takes a run of consecutive groups; thread 0 scans the runs.
    uint chunk = (uint(u_groups) + uint(GROUP) - 1u) / uint(GROUP);
    uint first = local * chunk, last = min(first + chunk, uint(u_groups));
    uint run_count = 0u;
    double run_work = 0.0LF;
    for (uint g = first; g < last; ++g) {
        run_count += groups[g].count;
        run_work += groups[g].work;
    }
    s_scan[local] = run_count;
    s_work[local] = run_work;
    barrier();
    if (local == 0u) {
        uint running = 0u;
        double sum = 0.0LF;
        for (uint t = 0u; t < uint(GROUP); ++t) {
            uint c = s_scan[t];
            s_scan[t] = running;
            running += c;
            sum += s_work[t];
        }
        total = running;
        pad = 0u;
        work = sum;
    }
    barrier();
    uint offset = s_scan[local];
    for (uint g = first; g < last; ++g) {
        groups[g].offset = offset;
        offset += groups[g].count;
    }
#else
    ivec2 ij;
    dvec4 rect;
    double area;
    vec2 depth_id;
    bool kept = texel_of(ij) && micro_patch(ij, rect, area, depth_id);
    s_scan[local] = kept ? 1u : 0u;
    barrier();
    for (uint step = 1u; step < uint(GROUP); step <<= 1) {          // inclusive scan (Hillis–Steele)
        uint add = local >= step ? s_scan[local - step] : 0u;
        barrier();
        s_scan[local] += add;
        barrier();
    }
    if (kept) {
        uint row = groups[gl_WorkGroupID.x].offset + s_scan[local] - 1u;
        patches[row] = Patch(vec4(rect), vec4(vec2(ij), depth_id));
    }
#endif
}
