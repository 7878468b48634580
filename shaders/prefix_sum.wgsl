// Exclusive prefix sum of a u32 array, one level of a multi-level scan.
//
// scan_blocks: each workgroup scans BLOCK = WG * ITEMS consecutive elements in
// place (exclusive) and writes the block's total to block_sums[block].  The
// host scans block_sums the same way (recursively) and then add_block_sums
// adds each block's exclusive offset to its elements.  No decoupled look-back
// and no subgroup operations: every level is a separate dispatch, so the scan
// needs no forward-progress guarantee between workgroups.

struct Params {
    n: u32,           // elements in `data`
    num_blocks: u32,  // ceil(n / BLOCK)
}

const WG: u32 = 256u;
const ITEMS: u32 = 8u;
const BLOCK: u32 = WG * ITEMS;  // the host reads it (r360gpu.render.scan)

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> block_sums: array<u32>;

//!include common.wgsl
//!include workgroup_scan.wgsl

// Exclusive scan of the threads' totals (256 threads: SCAN_SEG = 16).
fn scan_threads(tid: u32, own: u32) -> u32 {
    var v: ScanValue;
    v.lo = vec4<u32>(own, 0u, 0u, 0u);
    v.hi = vec4<u32>(0u);
    return workgroup_scan(tid, v).lo.x - own;
}

@compute @workgroup_size(WG)
fn scan_blocks(@builtin(local_invocation_index) tid: u32,
               @builtin(workgroup_id) wid: vec3<u32>,
               @builtin(num_workgroups) nwg: vec3<u32>) {
    let block = workgroup_index(wid, nwg);
    if (block >= p.num_blocks) {
        return;
    }
    // Each thread owns ITEMS consecutive elements, so a serial scan per thread
    // followed by a scan over threads keeps the order.
    let base = block * BLOCK + tid * ITEMS;
    var vals: array<u32, ITEMS>;
    var s = 0u;
    for (var k = 0u; k < ITEMS; k++) {
        let i = base + k;
        var v = 0u;
        if (i < p.n) {
            v = data[i];
        }
        vals[k] = s;
        s += v;
    }
    let excl = scan_threads(tid, s);
    for (var k = 0u; k < ITEMS; k++) {
        let i = base + k;
        if (i < p.n) {
            data[i] = vals[k] + excl;
        }
    }
    if (tid == WG - 1u) {
        block_sums[block] = excl + s;
    }
}

@compute @workgroup_size(WG)
fn add_block_sums(@builtin(local_invocation_index) tid: u32,
                  @builtin(workgroup_id) wid: vec3<u32>,
                  @builtin(num_workgroups) nwg: vec3<u32>) {
    let block = workgroup_index(wid, nwg);
    if (block >= p.num_blocks) {
        return;
    }
    let add = block_sums[block];
    for (var k = 0u; k < ITEMS; k++) {
        let i = block * BLOCK + k * WG + tid;
        if (i < p.n) {
            data[i] = data[i] + add;
        }
    }
}
