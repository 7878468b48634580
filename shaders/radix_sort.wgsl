// One pass of a portable LSD radix sort of (u32 key, u32 value) pairs on a
// 4-bit digit (16 buckets).
//
// Portability: no subgroup operations and no inter-workgroup communication
// inside a dispatch (no decoupled look-back, no spin-waiting), so it runs on
// any WebGPU implementation including software Vulkan, which gives no
// forward-progress guarantee between workgroups.  A pass is three dispatches:
//
//   histogram       per-block digit counts -> hist[digit * total_blocks + block]
//   (prefix_sum)    exclusive scan of hist -> global start of each (digit, block)
//   scatter         each block re-counts its digits, ranks its elements stably
//                   and writes them to their global positions.
//
// Stability: a thread owns ITEMS consecutive elements and counts them serially;
// the per-thread counts are scanned across threads in thread order, so equal
// digits keep their input order within a block, and blocks are ordered by the
// scanned histogram (digit-major, then block).
//
// Inputs larger than one storage binding are processed in windows: the host
// binds a window of the input (block_base = first global block of the window)
// and a window of the output ([out_base, out_base + out_count) in global
// element positions); the scatter writes only the elements that land inside
// the bound output window, so the host repeats it for every output window.

// 64 threads x 32 items: few SIMD slices per workgroup keeps barriers cheap on
// CPU implementations (which run the slices as coroutines); 2048 per block.
const WG: u32 = 64u;
const ITEMS: u32 = 32u;
const BLOCK: u32 = WG * ITEMS;
const DIGIT_BITS: u32 = 4u;
const RADIX: u32 = 1u << DIGIT_BITS;

// Digit counts are packed so they stay in registers (dynamically indexed
// arrays are slow on CPU implementations): while a thread counts its 32 items,
// 8-bit fields in a vec4 (digit d in component d / 4, bits 8 * (d % 4));
// across threads, 16-bit fields in two vec4 (digit d in word d / 2 of lo (d < 8)
// or hi, bits 16 * (d % 2)), which cannot overflow with 2048 per block.
// (lo: digits 0-7, hi: digits 8-15; scanned by workgroup_scan with SCAN_SEG = 8.)
//!include common.wgsl
//!include radix_pass.wgsl
//!include workgroup_scan.wgsl
//!include radix_digits.wgsl

// Packed digit counts (8-bit fields) of the ITEMS elements from `base` (within the window).
fn count_items(base: u32) -> vec4<u32> {
    var c = vec4<u32>(0u);
    for (var k = 0u; k < ITEMS; k++) {
        let i = base + k;
        if (i < p.n) {
            bump(&c, digit_of(keys_in[i]));
        }
    }
    return c;
}

@compute @workgroup_size(WG)
fn histogram(@builtin(local_invocation_index) tid: u32,
             @builtin(workgroup_id) wid: vec3<u32>,
             @builtin(num_workgroups) nwg: vec3<u32>) {
    let block = workgroup_index(wid, nwg);
    if (block >= p.num_blocks) {
        return;
    }
    let incl = workgroup_scan(tid, widen(count_items(block * BLOCK + tid * ITEMS)));
    // The last thread's inclusive counts are the block's totals.
    if (tid == WG - 1u) {
        for (var d = 0u; d < RADIX; d++) {
            hist[d * p.total_blocks + p.block_base + block] = field16(incl, d);
        }
    }
}

@compute @workgroup_size(WG)
fn scatter(@builtin(local_invocation_index) tid: u32,
           @builtin(workgroup_id) wid: vec3<u32>,
           @builtin(num_workgroups) nwg: vec3<u32>) {
    let block = workgroup_index(wid, nwg);
    if (block >= p.num_blocks) {
        return;
    }
    let base = block * BLOCK + tid * ITEMS;
    let own = widen(count_items(base));
    let incl = workgroup_scan(tid, own);
    // Global position of this thread's first element of each digit: the
    // block's scanned histogram plus the elements of that digit in earlier threads.
    let gblock = p.block_base + block;
    var start: array<vec4<u32>, 4>;
    for (var d = 0u; d < RADIX; d++) {
        start[d >> 2u][d & 3u] = hist[d * p.total_blocks + gblock] + field16(incl, d) - field16(own, d);
    }
    let s0 = start[0];
    let s1 = start[1];
    let s2 = start[2];
    let s3 = start[3];
    // Second pass over the thread's items (re-read rather than kept in a
    // dynamically indexed array), ranking each within its digit.
    var c = vec4<u32>(0u);
    for (var k = 0u; k < ITEMS; k++) {
        let i = base + k;
        if (i < p.n) {
            let key = keys_in[i];
            let d = digit_of(key);
            let q = d >> 2u;
            let sv = select(select(s0, s1, q == 1u), select(s2, s3, q == 3u), q >= 2u);
            let dest = sv[d & 3u] + bump(&c, d);
            if (dest >= p.out_base && dest - p.out_base < p.out_count) {
                keys_out[dest - p.out_base] = key;
                vals_out[dest - p.out_base] = vals_in[i];
            }
        }
    }
}
