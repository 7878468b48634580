// SSIM (Wang et al. 2004) of one image pair, valid region, and the squared
// difference sum behind PSNR.
//
// Host side and conventions: r360gpu/kernels/ssim.py (11-tap Gaussian
// window, sigma 1.5, C1 = (0.01 L)^2, C2 = (0.03 L)^2, population
// statistics; the map covers only windows wholly inside the image).
//
// Images: (rows, W, C) interleaved, read from `img_x` / `img_y` as u32
// words; IS_U8 = 1 (pipeline constant): one byte per sample (values
// 0..255, L = 255), else one f32 per sample (values 0..1, L = 1).  A chunk of rows is bound at
// a time; all indices below are relative to the chunk.
//
// Precision: f32 throughout, but variances and the covariance are never
// formed as E[x^2] - E[x]^2 (which cancels catastrophically on flat, bright
// regions).  The horizontal pass stores per-row window means and *centred*
// second moments; the vertical pass combines the 11 rows with the law of
// total variance: V = sum_j g_j v_j + sum_j g_j (m_j - M)^2.
//
// Entry points:
//   ssim_h   one invocation per (channel, input row, valid column c):
//            over x[c..c+10] of that row -> 5 planes of `hs`
//            (mean x, mean y, centred sum x^2, centred sum y^2, centred x*y).
//   ssim_v   one invocation per (channel, block of RB output rows, column):
//            combines rows y..y+10 of `hs`, evaluates SSIM, writes the f32 sum
//            of its RB values to partial[invocation] (host sums in f64).
//   sqdiff   one invocation per SQ words: sum of (x - y)^2 -> partial[invocation];
//            u8: words of 4 bytes, exact u32 sum (SQ*4*255^2 < 2^32), stored
//            bit for bit in the f32 array; float: f32 sum of SQ samples.

//!include common.wgsl

struct Params {
    width: u32,      // W (pixels per row)
    channels: u32,   // C
    rows_in: u32,    // input rows of this chunk
    rows_out: u32,   // valid output rows of this chunk (rows_in - 10)
    valid_w: u32,    // W - 10
    n_blocks: u32,   // ceil(rows_out / RB)
    pad4: u32,
    n_words: u32,    // sqdiff: words of the rows it sums (4 bytes or one f32 each)
    c1: f32,
    c2: f32,
    pad0: u32,
    pad1: u32,
    g0: f32,         // Gaussian taps g[0..5] (g[10 - k] = g[k]), from the host's window
    g1: f32,
    g2: f32,
    g3: f32,
    g4: f32,
    g5: f32,
    pad2: u32,
    pad3: u32,
};

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> img_x: array<u32>;
@group(0) @binding(2) var<storage, read> img_y: array<u32>;
@group(0) @binding(3) var<storage, read_write> hs: array<f32>;
@group(0) @binding(4) var<storage, read_write> partial: array<f32>;

const WG: u32 = 64u;
const RB: u32 = 16u;
const SQ: u32 = 16u;

// u8 input (1) or f32 input (0); a pipeline constant so the sample reads
// carry no per-invocation branch.
override IS_U8: u32 = 1u;

// The 11-tap weighted sum, symmetric taps paired.  Written out (no array, no
// loop over taps): CPU adapters keep everything in registers this way.
fn wsum(v0: f32, v1: f32, v2: f32, v3: f32, v4: f32, v5: f32, v6: f32, v7: f32, v8: f32, v9: f32,
        v10: f32) -> f32 {
    return P.g5 * v5 + P.g4 * (v4 + v6) + P.g3 * (v3 + v7) + P.g2 * (v2 + v8) + P.g1 * (v1 + v9)
        + P.g0 * (v0 + v10);
}

fn sample_x(e: u32) -> f32 {
    if (IS_U8 == 1u) {
        return f32((img_x[e >> 2u] >> ((e & 3u) * 8u)) & 0xffu);
    }
    return bitcast<f32>(img_x[e]);
}

fn sample_y(e: u32) -> f32 {
    if (IS_U8 == 1u) {
        return f32((img_y[e >> 2u] >> ((e & 3u) * 8u)) & 0xffu);
    }
    return bitcast<f32>(img_y[e]);
}

fn lin(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return workgroup_index(wid, nwg) * WG + lid;
}

// (mean, centred second moment, centred cross moment) of 11 values of x and y.
struct Moments {
    mx: f32,
    my: f32,
    vx: f32,
    vy: f32,
    cxy: f32,
};

fn moments(x0: f32, x1: f32, x2: f32, x3: f32, x4: f32, x5: f32, x6: f32, x7: f32, x8: f32, x9: f32, x10: f32,
           y0: f32, y1: f32, y2: f32, y3: f32, y4: f32, y5: f32, y6: f32, y7: f32, y8: f32, y9: f32,
           y10: f32) -> Moments {
    let mx = wsum(x0, x1, x2, x3, x4, x5, x6, x7, x8, x9, x10);
    let my = wsum(y0, y1, y2, y3, y4, y5, y6, y7, y8, y9, y10);
    let a0 = x0 - mx; let a1 = x1 - mx; let a2 = x2 - mx; let a3 = x3 - mx; let a4 = x4 - mx;
    let a5 = x5 - mx; let a6 = x6 - mx; let a7 = x7 - mx; let a8 = x8 - mx; let a9 = x9 - mx;
    let a10 = x10 - mx;
    let b0 = y0 - my; let b1 = y1 - my; let b2 = y2 - my; let b3 = y3 - my; let b4 = y4 - my;
    let b5 = y5 - my; let b6 = y6 - my; let b7 = y7 - my; let b8 = y8 - my; let b9 = y9 - my;
    let b10 = y10 - my;
    var m: Moments;
    m.mx = mx;
    m.my = my;
    m.vx = wsum(a0 * a0, a1 * a1, a2 * a2, a3 * a3, a4 * a4, a5 * a5, a6 * a6, a7 * a7, a8 * a8, a9 * a9,
                a10 * a10);
    m.vy = wsum(b0 * b0, b1 * b1, b2 * b2, b3 * b3, b4 * b4, b5 * b5, b6 * b6, b7 * b7, b8 * b8, b9 * b9,
                b10 * b10);
    m.cxy = wsum(a0 * b0, a1 * b1, a2 * b2, a3 * b3, a4 * b4, a5 * b5, a6 * b6, a7 * b7, a8 * b8, a9 * b9,
                 a10 * b10);
    return m;
}

@compute @workgroup_size(WG)
fn ssim_h(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_index) lid: u32) {
    let g = lin(wid, nwg, lid);
    let plane = P.channels * P.rows_in * P.valid_w;
    if (g >= plane) {
        return;
    }
    let c = g % P.valid_w;
    let rest = g / P.valid_w;
    let row = rest % P.rows_in;
    let ch = rest / P.rows_in;
    let e = (row * P.width + c) * P.channels + ch;
    let s = P.channels;
    let m = moments(
        sample_x(e), sample_x(e + s), sample_x(e + 2u * s), sample_x(e + 3u * s), sample_x(e + 4u * s),
        sample_x(e + 5u * s), sample_x(e + 6u * s), sample_x(e + 7u * s), sample_x(e + 8u * s),
        sample_x(e + 9u * s), sample_x(e + 10u * s),
        sample_y(e), sample_y(e + s), sample_y(e + 2u * s), sample_y(e + 3u * s), sample_y(e + 4u * s),
        sample_y(e + 5u * s), sample_y(e + 6u * s), sample_y(e + 7u * s), sample_y(e + 8u * s),
        sample_y(e + 9u * s), sample_y(e + 10u * s));
    hs[g] = m.mx;
    hs[plane + g] = m.my;
    hs[2u * plane + g] = m.vx;
    hs[3u * plane + g] = m.vy;
    hs[4u * plane + g] = m.cxy;
}

// Plane q of the horizontal statistics, 11 rows down from index i.
fn col(q: u32, i: u32) -> array<f32, 11> {
    let plane = P.channels * P.rows_in * P.valid_w;
    let o = q * plane + i;
    let s = P.valid_w;
    return array<f32, 11>(hs[o], hs[o + s], hs[o + 2u * s], hs[o + 3u * s], hs[o + 4u * s], hs[o + 5u * s],
                          hs[o + 6u * s], hs[o + 7u * s], hs[o + 8u * s], hs[o + 9u * s], hs[o + 10u * s]);
}

fn wsum_a(v: array<f32, 11>) -> f32 {
    return wsum(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9], v[10]);
}

@compute @workgroup_size(WG)
fn ssim_v(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_index) lid: u32) {
    let g = lin(wid, nwg, lid);
    if (g >= P.channels * P.n_blocks * P.valid_w) {
        return;
    }
    let c = g % P.valid_w;
    let rest = g / P.valid_w;
    let blk = rest % P.n_blocks;
    let ch = rest / P.n_blocks;
    let y0 = blk * RB;
    let y1 = min(y0 + RB, P.rows_out);
    var s: f32 = 0.0;
    for (var y = y0; y < y1; y = y + 1u) {
        let i = (ch * P.rows_in + y) * P.valid_w + c;
        // Law of total variance over the 11 rows: E[v_j] + Var[m_j].
        let a = col(0u, i);
        let b = col(1u, i);
        let m = moments(a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10],
                        b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9], b[10]);
        let vx = m.vx + wsum_a(col(2u, i));
        let vy = m.vy + wsum_a(col(3u, i));
        let cxy = m.cxy + wsum_a(col(4u, i));
        let num = (2.0 * m.mx * m.my + P.c1) * (2.0 * cxy + P.c2);
        let den = (m.mx * m.mx + m.my * m.my + P.c1) * (vx + vy + P.c2);
        s = s + num / den;
    }
    partial[g] = s;
}

@compute @workgroup_size(WG)
fn sqdiff(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_index) lid: u32) {
    let g = lin(wid, nwg, lid);
    let w0 = g * SQ;
    if (w0 >= P.n_words) {
        return;
    }
    let w1 = min(w0 + SQ, P.n_words);
    if (IS_U8 == 1u) {
        var s: u32 = 0u;
        for (var w = w0; w < w1; w = w + 1u) {
            let a = img_x[w];
            let b = img_y[w];
            for (var k = 0u; k < 4u; k = k + 1u) {
                let d = i32((a >> (8u * k)) & 0xffu) - i32((b >> (8u * k)) & 0xffu);
                s = s + u32(d * d);
            }
        }
        partial[g] = bitcast<f32>(s);
    } else {
        var s: f32 = 0.0;
        for (var w = w0; w < w1; w = w + 1u) {
            let d = bitcast<f32>(img_x[w]) - bitcast<f32>(img_y[w]);
            s = s + d * d;
        }
        partial[g] = s;
    }
}
