// Viewer overlays: one panel's picture from a rendered view, with overlays.
//
// Host side and conventions: viewer/overlays.py.
// Inputs are windows of the renderer's six-plane images (r360gpu/render/
// rasterize.py: planes r, g, b, alpha, depth, median_depth, each `stride`
// floats, row-major) at the panel's render size: the shown scene's r, g, b
// planes and depth plane, and pre's depth plane.
//   depth valid  = finite and > 0 (0 is "no coverage"), as depth_change.wgsl
//   dD           = |D_pre - D_scene| where both are valid, else 0
//   bin(dD)      = clamp(floor((dD - dd_lo) * dd_scale), 0, 255) (the geometric
//                  axis' histogram binning); changed = bin(dD) > dd_split (GHT)
// Output: one packed rgba8 (pack4x8unorm) per pixel, sRGB-encoded colours.
//
// Entry points:
//   overlay      the panel picture
//   depth_range  min / max of the valid depths -> stats[0], stats[1] (f32 bits;
//                depths are > 0, so u32 order = float order)

//!include common.wgsl

struct Params {
    width: u32,
    height: u32,
    stride: u32,        // floats per plane
    flags: u32,         // bit 0 depth, 1 |dD| heat, 2 changed, 3 outline, 4 probes, 5 pre valid, 6 mask valid, 7 probes valid
    outline_px: u32,    // outline half-width in render pixels (>= 1)
    pad0: u32,
    pad2: u32,
    pad1: u32,
    depth_lo: f32,      // colour-map range of the depth overlay
    depth_hi: f32,
    heat_lo: f32,       // colour-map range of the |dD| heat map
    heat_hi: f32,
    dd_lo: f32,         // histogram binning of dD (r360gpu.kernels.depth_change)
    dd_scale: f32,
    dd_split: f32,      // GHT split in bins; changed = bin > split
    opacity: f32,
};

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> scene_rgb: array<f32>;     // planes r, g, b
@group(0) @binding(2) var<storage, read> scene_depth: array<f32>;
@group(0) @binding(3) var<storage, read> pre_depth: array<f32>;
@group(0) @binding(4) var<storage, read> mask_words: array<u32>;   // target mask, 1 bit per pixel
@group(0) @binding(5) var<storage, read> probe_ids: array<u32>;    // probe instance id + 1 per pixel, 0 = none
@group(0) @binding(6) var<storage, read> cmap: array<vec4<f32>>;   // 256-entry colour map
@group(0) @binding(7) var<storage, read_write> out_rgba: array<u32>;
@group(0) @binding(8) var<storage, read_write> stats: array<atomic<u32>>;

const F32_MAX: f32 = 3.40282347e38;
const HEAT_BELOW: f32 = 0.35;   // heat-map opacity factor below the GHT threshold
const CHANGED_RGB: vec3<f32> = vec3<f32>(1.0, 0.1, 0.75);
const OUTLINE_RGB: vec3<f32> = vec3<f32>(1.0, 0.86, 0.0);

fn valid(d: f32) -> bool {
    return d > 0.0 && d <= F32_MAX;
}

fn has(bit: u32) -> bool {
    return (P.flags & (1u << bit)) != 0u;
}

fn colour(x: f32) -> vec3<f32> {
    let i = u32(floor(clamp(x, 0.0, 1.0) * 255.0 + 0.5));
    return cmap[i].rgb;
}

fn norm(x: f32, lo: f32, hi: f32) -> f32 {
    if (hi > lo) {
        return (x - lo) / (hi - lo);
    }
    return 0.0;
}

fn in_mask(x: i32, y: i32) -> bool {
    if (x < 0 || y < 0 || x >= i32(P.width) || y >= i32(P.height)) {
        return false;
    }
    let i = u32(y) * P.width + u32(x);
    return (mask_words[i / 32u] & (1u << (i % 32u))) != 0u;
}

// A distinct colour per probe instance (golden-ratio hue steps).
fn instance_rgb(id: u32) -> vec3<f32> {
    let h = fract(f32(id) * 0.618034);
    let k = vec3<f32>(0.0, 2.0 / 3.0, 1.0 / 3.0);
    return clamp(abs(fract(vec3<f32>(h) + k) * 6.0 - 3.0) - 1.0, vec3<f32>(0.0), vec3<f32>(1.0));
}

@compute @workgroup_size(8, 8)
fn overlay(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= P.width || gid.y >= P.height) {
        return;
    }
    let i = gid.y * P.width + gid.x;
    let s = P.stride;
    var c = clamp(vec3<f32>(scene_rgb[i], scene_rgb[s + i], scene_rgb[2u * s + i]), vec3<f32>(0.0), vec3<f32>(1.0));
    let a = P.opacity;
    let d = scene_depth[i];
    if (has(0u) && valid(d)) {
        c = mix(c, colour(norm(d, P.depth_lo, P.depth_hi)), a);
    }
    if (has(5u) && (has(1u) || has(2u))) {
        let dp = pre_depth[i];
        var dd = 0.0;
        if (valid(d) && valid(dp)) {
            dd = abs(dp - d);
        }
        let b = clamp(floor((dd - P.dd_lo) * P.dd_scale), 0.0, 255.0);
        let changed = b > P.dd_split;
        if (has(1u)) {
            var w = a;
            if (!changed) {
                w = a * HEAT_BELOW;
            }
            c = mix(c, colour(norm(dd, P.heat_lo, P.heat_hi)), w);
        }
        if (has(2u) && changed) {
            c = mix(c, CHANGED_RGB, a);
        }
    }
    if (has(4u) && has(7u)) {
        let id = probe_ids[i];
        if (id != 0u) {
            c = mix(c, instance_rgb(id), a * 0.6);
        }
    }
    if (has(3u) && has(6u)) {
        let x = i32(gid.x);
        let y = i32(gid.y);
        let r = i32(P.outline_px);
        let inside = in_mask(x, y);
        // A boundary pixel: inside, with an outside pixel within r along an axis.
        if (inside && !(in_mask(x - r, y) && in_mask(x + r, y) && in_mask(x, y - r) && in_mask(x, y + r))) {
            c = OUTLINE_RGB;
        }
    }
    out_rgba[i] = pack4x8unorm(vec4<f32>(c, 1.0));
}

// One invocation per depth value, RWG per workgroup.
const RWG: u32 = 64u;

@compute @workgroup_size(RWG)
fn depth_range(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
               @builtin(local_invocation_index) lid: u32) {
    let i = workgroup_index(wid, nwg) * RWG + lid;
    if (i >= P.width * P.height) {
        return;
    }
    let d = scene_depth[i];
    if (valid(d)) {
        atomicMin(&stats[0], bitcast<u32>(d));
        atomicMax(&stats[1], bitcast<u32>(d));
    }
}
