// Interleaves the r, g, b planes of a rendered image (render_rasterize.wgsl's
// output layout) into one pixel-major array, out[3 i + c] = plane c [i], so the
// host reads numpy's (H, W, 3) layout directly instead of interleaving on the CPU.
// Words are copied as u32: the bits of every value (NaN, infinities) are kept.

//!include common.wgsl

struct Params {
    n: u32,  // pixels (width * height)
}

// Invocations per workgroup, one per pixel; the host reads it (gpu.shaders.workgroup_threads).
const WG: u32 = 256u;

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> plane_r: array<u32>;
@group(0) @binding(2) var<storage, read> plane_g: array<u32>;
@group(0) @binding(3) var<storage, read> plane_b: array<u32>;
@group(0) @binding(4) var<storage, read_write> out: array<u32>;

@compute @workgroup_size(WG)
fn main(@builtin(local_invocation_index) tid: u32,
        @builtin(workgroup_id) wid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = workgroup_index(wid, nwg) * WG + tid;
    if (i < p.n) {
        out[3u * i] = plane_r[i];
        out[3u * i + 1u] = plane_g[i];
        out[3u * i + 2u] = plane_b[i];
    }
}
