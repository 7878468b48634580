// One pass of a stable LSD radix sort of (u32 key, u32 value) pairs on a digit
// of up to 8 bits (256 buckets), laid out for GPUs: every global read of a
// block is coalesced (consecutive threads, consecutive elements), the block is
// sorted by the digit in workgroup memory, and the writes go out in runs of
// equal digits (consecutive threads, consecutive destinations).
// radix_sort.wgsl is the variant for CPU implementations (one thread walks 32
// consecutive elements; r360gpu.render.sort picks the variant per adapter);
// both give the same permutation.
//
// Portability as radix_sort.wgsl: no subgroup operations, no inter-workgroup
// communication inside a dispatch; workgroup memory stays under WebGPU's
// guaranteed 16 KiB.  A pass is three dispatches:
//
//   histogram       per-block digit counts -> hist[digit * total_blocks + block]
//                   (workgroup atomics: counts do not depend on the order)
//   (prefix_sum)    exclusive scan of hist -> global start of each (digit, block)
//   scatter         loads the block, sorts it stably by the digit in workgroup
//                   memory (two stable rounds on its 4-bit halves, each a
//                   count + scan over threads that own ITEMS consecutive
//                   entries), then writes element i of the sorted block to
//                   start(digit, block) + i - (first i of that digit).
//
// Workgroup memory holds one u32 per element, (digit << 16) | index in the
// block; keys and values are read again from global memory by index at the
// end (the block's 8 KiB are in cache by then).  Elements past the input's end
// enter the last block with the all-ones digit and an index after every real
// element, so a stable sort leaves them behind all real ones.
//
// Windows (inputs beyond one storage binding): as radix_sort.wgsl, the host
// binds one input window (block_base = its first global block) and one output
// window ([out_base, out_base + out_count) in global positions) per dispatch;
// the scatter writes only what lands inside the bound output window.

// 256 threads x 4 items: 1,024 elements per block (indices fit 16 bits).
const WG: u32 = 256u;
const ITEMS: u32 = 4u;
const BLOCK: u32 = WG * ITEMS;
const DIGIT_BITS: u32 = 8u;
const RADIX: u32 = 1u << DIGIT_BITS;

//!include common.wgsl
//!include radix_pass.wgsl
//!include workgroup_scan.wgsl
//!include radix_digits.wgsl

// The block's entries, (digit << 16) | index; slot(i) pads one word every ITEMS
// so a thread's ITEMS consecutive entries (stride ITEMS + 1 across threads)
// fall in different banks.
var<workgroup> entries: array<u32, BLOCK + BLOCK / ITEMS>;
// histogram: the block's digit counts.
var<workgroup> digit_count: array<atomic<u32>, RADIX>;
// scatter: per digit, its global destination minus its first position in the sorted block.
var<workgroup> digit_offset: array<u32, RADIX>;
// Start of each 4-bit half-digit in the block during one sorting round.
var<workgroup> half_start: array<u32, 16>;

fn slot(i: u32) -> u32 {
    return i + i / ITEMS;
}

@compute @workgroup_size(WG)
fn histogram(@builtin(local_invocation_index) tid: u32,
             @builtin(workgroup_id) wid: vec3<u32>,
             @builtin(num_workgroups) nwg: vec3<u32>) {
    let block = workgroup_index(wid, nwg);
    if (block >= p.num_blocks) {
        return;
    }
    for (var d = tid; d < RADIX; d += WG) {
        atomicStore(&digit_count[d], 0u);
    }
    workgroupBarrier();
    for (var k = 0u; k < ITEMS; k++) {
        let i = block * BLOCK + k * WG + tid;
        if (i < p.n) {
            atomicAdd(&digit_count[digit_of(keys_in[i])], 1u);
        }
    }
    workgroupBarrier();
    for (var d = tid; d < RADIX; d += WG) {
        hist[d * p.total_blocks + p.block_base + block] = atomicLoad(&digit_count[d]);
    }
}

// One stable round: reorders `entries` by the 4-bit half of the digit at
// `half` (0: low, 4: high) bits, keeping the order of equal halves.
fn sort_round(tid: u32, half: u32) {
    let first = tid * ITEMS;
    var e: array<u32, ITEMS>;
    var rank: array<u32, ITEMS>;
    var c = vec4<u32>(0u);
    for (var k = 0u; k < ITEMS; k++) {
        e[k] = entries[slot(first + k)];
        rank[k] = bump(&c, (e[k] >> (16u + half)) & 15u);
    }
    let own = widen(c);
    // Every read of `entries` above happens before the scan's barriers, so the
    // writes below cannot clobber an entry another thread has yet to read.
    let incl = workgroup_scan(tid, own);
    if (tid == WG - 1u) {
        // The last thread's inclusive counts are the block's totals per half-digit.
        var s = 0u;
        for (var d = 0u; d < 16u; d++) {
            half_start[d] = s;
            s += field16(incl, d);
        }
    }
    workgroupBarrier();
    for (var k = 0u; k < ITEMS; k++) {
        let d = (e[k] >> (16u + half)) & 15u;
        entries[slot(half_start[d] + field16(incl, d) - field16(own, d) + rank[k])] = e[k];
    }
    workgroupBarrier();
}

@compute @workgroup_size(WG)
fn scatter(@builtin(local_invocation_index) tid: u32,
           @builtin(workgroup_id) wid: vec3<u32>,
           @builtin(num_workgroups) nwg: vec3<u32>) {
    let block = workgroup_index(wid, nwg);
    if (block >= p.num_blocks) {
        return;
    }
    let base = block * BLOCK;
    let valid = min(BLOCK, p.n - base);
    let pad_digit = (1u << p.digit_bits) - 1u;
    for (var k = 0u; k < ITEMS; k++) {
        let i = k * WG + tid;
        var d = pad_digit;
        if (i < valid) {
            d = digit_of(keys_in[base + i]);
        }
        entries[slot(i)] = (d << 16u) | i;
    }
    workgroupBarrier();
    sort_round(tid, 0u);
    sort_round(tid, 4u);
    // First sorted position of each digit present -> destination offset.
    let gblock = p.block_base + block;
    for (var k = 0u; k < ITEMS; k++) {
        let i = k * WG + tid;
        if (i < valid) {
            let d = entries[slot(i)] >> 16u;
            if (i == 0u || (entries[slot(i - 1u)] >> 16u) != d) {
                digit_offset[d] = hist[d * p.total_blocks + gblock] - i;  // wraps; + i below undoes it
            }
        }
    }
    workgroupBarrier();
    for (var k = 0u; k < ITEMS; k++) {
        let i = k * WG + tid;
        if (i < valid) {
            let e = entries[slot(i)];
            let dest = digit_offset[e >> 16u] + i;
            if (dest >= p.out_base && dest - p.out_base < p.out_count) {
                let src = base + (e & 0xffffu);
                keys_out[dest - p.out_base] = keys_in[src];
                vals_out[dest - p.out_base] = vals_in[src];
            }
        }
    }
}
