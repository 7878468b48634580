// Tile ranges: after the keys (window-local tile ids) are sorted, writes
// ranges[2t], ranges[2t+1] = (start, end) of tile t's run in the key list.  The host clears
// `ranges` to zero first, so tiles without keys get the empty range (0, 0).

//!include common.wgsl

struct Params {
    n: u32,  // keys
}

// Invocations per workgroup, one per element; the host reads it (gpu.shaders.workgroup_threads).
const WG: u32 = 256u;

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> keys: array<u32>;
@group(0) @binding(2) var<storage, read_write> ranges: array<u32>;

@compute @workgroup_size(WG)
fn main(@builtin(local_invocation_index) lidx: u32,
        @builtin(workgroup_id) wid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = workgroup_index(wid, nwg) * WG + lidx;
    if (k >= p.n) {
        return;
    }
    let t = keys[k];
    if (k == 0u || keys[k - 1u] != t) {
        ranges[2u * t] = k;
    }
    if (k + 1u == p.n || keys[k + 1u] != t) {
        ranges[2u * t + 1u] = k + 1u;
    }
}
