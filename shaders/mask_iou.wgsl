// Batched binary-mask overlap on bit-packed masks.
//
// Layout of a packed stack chunk (host side: r360gpu/kernels/mask_iou.py):
//   each mask is n_rows rows of row_words u32 words; bit b of word c of row r
//   is pixel (r, 32 * c + b).  Mask k of the chunk starts at word
//   k * n_rows * row_words.
//   boxes[k] = (r0, r1, c0, c1): rows r0 <= r < r1 and words c0 <= c < c1
//   hold every set bit of mask k (an empty mask has r1 <= r0).  A pair only
//   visits the overlap of its two boxes, which is exact: a bit outside either
//   box is zero in that mask.
//
// Entry points:
//   intersect  one workgroup per (i, j) pair: out[i * n_b + j] = |a_i & b_j|
//   area       one workgroup per mask:        out[k] = |a_k|
//   union_or   one invocation per word:        out[w] = OR_k a_k[w]
//   pack       one invocation per output word: packs u32-per-pixel masks that
//              already live on the device (0 = outside, else inside) and
//              records their boxes with atomics.

//!include common.wgsl

struct Params {
    n_a: u32,        // masks in A (chunk)
    n_b: u32,        // masks in B (chunk)
    n_rows: u32,     // rows per mask in this chunk
    row_words: u32,  // words per row
    base: u32,       // intersect: first A row-of-matrix of this dispatch; pack: first input element
    width: u32,      // pack: pixels per row
    mask_px: u32,    // pack: pixels per whole input mask (H * W)
    pad: u32,
};

const WG: u32 = 64u;

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> a_words: array<u32>;
@group(0) @binding(2) var<storage, read> a_boxes: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> b_words: array<u32>;
@group(0) @binding(4) var<storage, read> b_boxes: array<vec4<u32>>;
@group(0) @binding(5) var<storage, read_write> out: array<u32>;
@group(0) @binding(6) var<storage, read_write> out_boxes: array<atomic<u32>>;

var<workgroup> acc: atomic<u32>;

fn box_sum_and(oa: u32, ob: u32, r0: u32, r1: u32, c0: u32, c1: u32, lid: u32) -> u32 {
    var s: u32 = 0u;
    // Threads take word columns; rows are walked in order so each thread
    // streams down a column of both masks.
    for (var c = c0 + lid; c < c1; c = c + WG) {
        for (var r = r0; r < r1; r = r + 1u) {
            let w = r * P.row_words + c;
            s = s + countOneBits(a_words[oa + w] & b_words[ob + w]);
        }
    }
    return s;
}

@compute @workgroup_size(WG)
fn intersect(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    // x indexes B (columns), y indexes A rows; `base` offsets A when one
    // chunk is split over several dispatches so each output fits a binding.
    let j = wid.x;
    let i = wid.y + P.base;
    if (lid == 0u) {
        atomicStore(&acc, 0u);
    }
    workgroupBarrier();
    let ba = a_boxes[i];
    let bb = b_boxes[j];
    let r0 = max(ba.x, bb.x);
    let r1 = min(ba.y, bb.y);
    let c0 = max(ba.z, bb.z);
    let c1 = min(ba.w, bb.w);
    let mask_words = P.n_rows * P.row_words;
    if (r0 < r1 && c0 < c1) {
        let s = box_sum_and(i * mask_words, j * mask_words, r0, r1, c0, c1, lid);
        if (s != 0u) {
            atomicAdd(&acc, s);
        }
    }
    workgroupBarrier();
    if (lid == 0u) {
        out[wid.y * P.n_b + j] = atomicLoad(&acc);
    }
}

@compute @workgroup_size(WG)
fn area(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
        @builtin(local_invocation_index) lid: u32) {
    let k = workgroup_index(wid, nwg);
    if (lid == 0u) {
        atomicStore(&acc, 0u);
    }
    workgroupBarrier();
    if (k < P.n_a) {
        let b = a_boxes[k];
        let o = k * P.n_rows * P.row_words;
        var s: u32 = 0u;
        for (var c = b.z + lid; c < b.w; c = c + WG) {
            for (var r = b.x; r < b.y; r = r + 1u) {
                s = s + countOneBits(a_words[o + r * P.row_words + c]);
            }
        }
        if (s != 0u) {
            atomicAdd(&acc, s);
        }
    }
    workgroupBarrier();
    if (lid == 0u && k < P.n_a) {
        out[k] = atomicLoad(&acc);
    }
}

@compute @workgroup_size(WG)
fn union_or(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let w = gid.x + gid.y * nwg.x * WG;
    let mask_words = P.n_rows * P.row_words;
    if (w >= mask_words) {
        return;
    }
    let r = w / P.row_words;
    let c = w % P.row_words;
    var v: u32 = 0u;
    for (var k = 0u; k < P.n_a; k = k + 1u) {
        let b = a_boxes[k];
        if (r >= b.x && r < b.y && c >= b.z && c < b.w) {
            v = v | a_words[k * mask_words + w];
        }
    }
    out[w] = v;
}

// pack: the caller's u32-per-pixel masks are bound as b_words; element
// `base` is pixel (row 0 of this chunk, column 0) of the chunk's first mask,
// and consecutive masks are mask_px elements apart.  out_boxes holds 4
// atomics per mask, initialised by the host to (n_rows, 0, row_words, 0).
@compute @workgroup_size(WG)
fn pack(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let g = gid.x + gid.y * nwg.x * WG;
    let mask_words = P.n_rows * P.row_words;
    if (g >= P.n_a * mask_words) {
        return;
    }
    let k = g / mask_words;
    let w = g % mask_words;
    let r = w / P.row_words;
    let c = w % P.row_words;
    let e0 = P.base + k * P.mask_px + r * P.width + c * 32u;
    var v: u32 = 0u;
    for (var b = 0u; b < 32u; b = b + 1u) {
        if (c * 32u + b < P.width && b_words[e0 + b] != 0u) {
            v = v | (1u << b);
        }
    }
    out[g] = v;
    if (v != 0u) {
        atomicMin(&out_boxes[4u * k], r);
        atomicMax(&out_boxes[4u * k + 1u], r + 1u);
        atomicMin(&out_boxes[4u * k + 2u], c);
        atomicMax(&out_boxes[4u * k + 3u], c + 1u);
    }
}
