// Geometric axis of one view: depth change, its histogram, changed pixels.
//
// Host side and conventions: r360gpu/kernels/depth_change.py.
//   valid depth  = finite and > 0 (0 is "no coverage"); if either depth of a
//                  pixel is invalid, dD = 0 (the reference convention).
//   bin(dD)      = clamp(floor((dD - lo) * scale), 0, 255), scale = 256 / (hi - lo)
//                  computed on the host in f32 (0 when hi == lo).
//   changed      = bin(dD) > t, with t the GHT split (fractional when GHT ties).
// The same bin() is used for the histogram and for the changed test, so the
// changed mask agrees with the histogram split exactly.
//
// Data are read as vec4 (four pixels of the chunk's flat row-major raster);
// buffers are padded to whole vec4s and lanes at or past n_px are ignored.
// The changed mask is written flat: bit b of word g is pixel 32 g + b.
//
// Entry points (one chunk of rows at a time):
//   delta_minmax   dD -> delta[]; min/max of dD -> stats[0], stats[1]
//                  (u32 bit patterns: dD >= 0, so u32 order = float order);
//                  the pixels with no depth after removal (D_post invalid)
//                  -> nd_words[] (bit b of word g is pixel 32 g + b, as
//                  changed_words; zero-initialised by the host)
//   histo          256-bin histogram, workgroup-shared atomics (GPUs)
//   histo_private  256-bin histogram, per-invocation private counts (CPU adapters)
//   changed        changed bits -> changed_words[]; |changed & M| -> stats[2];
//                  |M| -> stats[3]; |no depth after removal & M| -> stats[4]

//!include common.wgsl

struct Params {
    n_px: u32,     // pixels in this chunk
    pad0: u32,
    pad1: u32,
    pad2: u32,
    lo: f32,
    scale: f32,
    t: f32,
    pad3: u32,
};

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> d_pre: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> d_post: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> delta: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> stats: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read_write> hist: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read> m_words: array<u32>;
@group(0) @binding(7) var<storage, read_write> changed_words: array<u32>;
@group(0) @binding(8) var<storage, read_write> nd_words: array<atomic<u32>>;

const F32_MAX: f32 = 3.40282347e38;

fn valid4(d: vec4<f32>) -> vec4<bool> {
    // d > 0 is false for NaN; the upper bound rejects +Inf.
    return (d > vec4<f32>(0.0)) & (d <= vec4<f32>(F32_MAX));
}

// Lanes of vec4 number q that hold pixels of this chunk.
fn lanes(q: u32) -> vec4<bool> {
    let first = 4u * q;
    return vec4<u32>(first, first + 1u, first + 2u, first + 3u) < vec4<u32>(P.n_px);
}

fn bin4(x: vec4<f32>) -> vec4<u32> {
    return vec4<u32>(clamp(floor((x - vec4<f32>(P.lo)) * P.scale), vec4<f32>(0.0), vec4<f32>(255.0)));
}

fn n_vec() -> u32 {
    return (P.n_px + 3u) / 4u;
}

// delta_minmax: QV vec4s per invocation, WG apart, so neighbouring
// invocations read neighbouring memory.  One global atomic pair per
// invocation (a tree reduction's barriers cost more on CPU adapters).
const WG: u32 = 64u;
const QV: u32 = 4u;

@compute @workgroup_size(WG)
fn delta_minmax(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                @builtin(local_invocation_index) lid: u32) {
    let base = workgroup_index(wid, nwg) * WG * QV + lid;
    var lo = vec4<f32>(F32_MAX);
    var hi = vec4<f32>(0.0);
    let nq = n_vec();
    for (var k = 0u; k < QV; k = k + 1u) {
        let q = base + k * WG;
        if (q < nq) {
            let a = d_pre[q];
            let b = d_post[q];
            let vb = valid4(b);
            let d = select(vec4<f32>(0.0), abs(a - b), valid4(a) & vb);
            delta[q] = d;
            let inside = lanes(q);
            // vec4 q holds pixels 4q..4q+3: bits 4(q % 8).. of word q / 8 (8 vec4s a word,
            // written by up to 8 invocations: an atomic OR).
            let nd = (!vb) & inside;
            let nib = select(0u, 1u, nd.x) | select(0u, 2u, nd.y) | select(0u, 4u, nd.z) | select(0u, 8u, nd.w);
            if (nib != 0u) {
                atomicOr(&nd_words[q / 8u], nib << (4u * (q % 8u)));
            }
            lo = min(lo, select(vec4<f32>(F32_MAX), d, inside));
            hi = max(hi, select(vec4<f32>(0.0), d, inside));
        }
    }
    let l = min(min(lo.x, lo.y), min(lo.z, lo.w));
    let h = max(max(hi.x, hi.y), max(hi.z, hi.w));
    if (l < F32_MAX) {
        atomicMin(&stats[0], bitcast<u32>(l));
        atomicMax(&stats[1], bitcast<u32>(h));
    }
}

// Histogram, GPU flavour: a workgroup-shared histogram (one shared atomic
// per pixel, cheap on GPUs), merged into `hist` with global atomics.
// One invocation per bin: the workgroup has N_BINS invocations.
const N_BINS: u32 = 256u;
var<workgroup> wg_hist: array<atomic<u32>, N_BINS>;

@compute @workgroup_size(N_BINS)
fn histo(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
         @builtin(local_invocation_index) lid: u32) {
    atomicStore(&wg_hist[lid], 0u);
    workgroupBarrier();
    let nq = n_vec();
    let base = workgroup_index(wid, nwg) * N_BINS * QV + lid;
    for (var k = 0u; k < QV; k = k + 1u) {
        let q = base + k * N_BINS;
        if (q < nq) {
            let b = bin4(delta[q]);
            let inside = lanes(q);
            for (var i = 0u; i < 4u; i = i + 1u) {
                if (inside[i]) {
                    atomicAdd(&wg_hist[b[i]], 1u);
                }
            }
        }
    }
    workgroupBarrier();
    let c = atomicLoad(&wg_hist[lid]);
    if (c != 0u) {
        atomicAdd(&hist[lid], c);
    }
}

// Histogram, CPU flavour: each invocation counts HQ vec4s into its own
// private histogram with plain increments, then merges its non-zero bins.
// On CPU adapters (lavapipe) this beats shared-memory atomics.
const HWG: u32 = 16u;
const HQ: u32 = 256u;

@compute @workgroup_size(HWG)
fn histo_private(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                 @builtin(local_invocation_index) lid: u32) {
    var h: array<u32, N_BINS>;
    let nq = n_vec();
    let base = workgroup_index(wid, nwg) * HWG * HQ + lid;
    for (var k = 0u; k < HQ; k = k + 1u) {
        let q = base + k * HWG;
        if (q < nq) {
            let b = bin4(delta[q]);
            let inside = lanes(q);
            for (var i = 0u; i < 4u; i = i + 1u) {
                if (inside[i]) {
                    h[b[i]] = h[b[i]] + 1u;
                }
            }
        }
    }
    for (var b = 0u; b < N_BINS; b = b + 1u) {
        if (h[b] != 0u) {
            atomicAdd(&hist[b], h[b]);
        }
    }
}

// changed: one invocation per output word (32 pixels = 8 vec4s), CWG words per workgroup.
const CWG: u32 = 64u;
var<workgroup> wg_in: atomic<u32>;
var<workgroup> wg_m: atomic<u32>;
var<workgroup> wg_nd: atomic<u32>;

@compute @workgroup_size(CWG)
fn changed(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
           @builtin(local_invocation_index) lid: u32) {
    if (lid == 0u) {
        atomicStore(&wg_in, 0u);
        atomicStore(&wg_m, 0u);
        atomicStore(&wg_nd, 0u);
    }
    workgroupBarrier();
    let g = workgroup_index(wid, nwg) * CWG + lid;
    let n_words = (P.n_px + 31u) / 32u;
    if (g < n_words) {
        var v: u32 = 0u;
        for (var k = 0u; k < 8u; k = k + 1u) {
            let q = 8u * g + k;
            let c = (vec4<f32>(bin4(delta[q])) > vec4<f32>(P.t)) & lanes(q);
            let nib = select(0u, 1u, c.x) | select(0u, 2u, c.y) | select(0u, 4u, c.z) | select(0u, 8u, c.w);
            v = v | (nib << (4u * k));
        }
        changed_words[g] = v;
        let m = m_words[g];
        let s_in = countOneBits(v & m);
        let s_m = countOneBits(m);
        let s_nd = countOneBits(atomicLoad(&nd_words[g]) & m);
        if (s_in != 0u) {
            atomicAdd(&wg_in, s_in);
        }
        if (s_m != 0u) {
            atomicAdd(&wg_m, s_m);
        }
        if (s_nd != 0u) {
            atomicAdd(&wg_nd, s_nd);
        }
    }
    workgroupBarrier();
    if (lid == 0u) {
        atomicAdd(&stats[2], atomicLoad(&wg_in));
        atomicAdd(&stats[3], atomicLoad(&wg_m));
        atomicAdd(&stats[4], atomicLoad(&wg_nd));
    }
}
