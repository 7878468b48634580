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
// Entry points (one chunk of rows at a time):
//   delta    dD per pixel -> delta[]; min/max of dD -> stats[0], stats[1]
//            (as u32 bit patterns: dD >= 0, so u32 order = float order)
//   histo    256-bin histogram of delta[] -> hist[] (workgroup-private
//            histograms merged with atomics)
//   changed  one invocation per packed word (32 px of a row): changed bits ->
//            changed_words[]; |changed & M| -> stats[2]; |M| -> stats[3]

struct Params {
    n_rows: u32,
    width: u32,
    row_words: u32,
    pad0: u32,
    lo: f32,
    scale: f32,
    t: f32,
    pad1: u32,
};

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> d_pre: array<f32>;
@group(0) @binding(2) var<storage, read> d_post: array<f32>;
@group(0) @binding(3) var<storage, read_write> delta: array<f32>;
@group(0) @binding(4) var<storage, read_write> stats: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read_write> hist: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read> m_words: array<u32>;
@group(0) @binding(7) var<storage, read_write> changed_words: array<u32>;

const WG: u32 = 256u;
const F32_MAX: f32 = 3.40282347e38;

var<workgroup> wg_min: atomic<u32>;
var<workgroup> wg_max: atomic<u32>;
var<workgroup> wg_hist: array<atomic<u32>, 256>;
var<workgroup> wg_a: atomic<u32>;
var<workgroup> wg_b: atomic<u32>;

fn valid(d: f32) -> bool {
    // d > 0 is false for NaN; the upper bound rejects +Inf.
    return d > 0.0 && d <= F32_MAX;
}

fn bin_of(x: f32) -> f32 {
    return clamp(floor((x - P.lo) * P.scale), 0.0, 255.0);
}

@compute @workgroup_size(256)
fn delta_minmax(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                @builtin(local_invocation_index) lid: u32) {
    if (lid == 0u) {
        atomicStore(&wg_min, 0xffffffffu);
        atomicStore(&wg_max, 0u);
    }
    workgroupBarrier();
    let p = gid.x + gid.y * nwg.x * WG;
    if (p < P.n_rows * P.width) {
        let a = d_pre[p];
        let b = d_post[p];
        var d: f32 = 0.0;
        if (valid(a) && valid(b)) {
            d = abs(a - b);
        }
        delta[p] = d;
        let bits = bitcast<u32>(d);
        atomicMin(&wg_min, bits);
        atomicMax(&wg_max, bits);
    }
    workgroupBarrier();
    if (lid == 0u) {
        atomicMin(&stats[0], atomicLoad(&wg_min));
        atomicMax(&stats[1], atomicLoad(&wg_max));
    }
}

@compute @workgroup_size(256)
fn histo(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
         @builtin(local_invocation_index) lid: u32) {
    atomicStore(&wg_hist[lid], 0u);
    workgroupBarrier();
    let p = gid.x + gid.y * nwg.x * WG;
    if (p < P.n_rows * P.width) {
        atomicAdd(&wg_hist[u32(bin_of(delta[p]))], 1u);
    }
    workgroupBarrier();
    let c = atomicLoad(&wg_hist[lid]);
    if (c != 0u) {
        atomicAdd(&hist[lid], c);
    }
}

@compute @workgroup_size(256)
fn changed(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
           @builtin(local_invocation_index) lid: u32) {
    if (lid == 0u) {
        atomicStore(&wg_a, 0u);
        atomicStore(&wg_b, 0u);
    }
    workgroupBarrier();
    let g = gid.x + gid.y * nwg.x * WG;
    if (g < P.n_rows * P.row_words) {
        let r = g / P.row_words;
        let c = g % P.row_words;
        var v: u32 = 0u;
        for (var b = 0u; b < 32u; b = b + 1u) {
            let x = c * 32u + b;
            if (x < P.width && bin_of(delta[r * P.width + x]) > P.t) {
                v = v | (1u << b);
            }
        }
        changed_words[g] = v;
        let m = m_words[g];
        let s_in = countOneBits(v & m);
        let s_m = countOneBits(m);
        if (s_in != 0u) {
            atomicAdd(&wg_a, s_in);
        }
        if (s_m != 0u) {
            atomicAdd(&wg_b, s_m);
        }
    }
    workgroupBarrier();
    if (lid == 0u) {
        atomicAdd(&stats[2], atomicLoad(&wg_a));
        atomicAdd(&stats[3], atomicLoad(&wg_b));
    }
}
