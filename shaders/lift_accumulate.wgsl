// Target lifting: per-Gaussian compositing weight inside and outside a 2D
// target mask (r360gpu/lift/device.py; numpy reference tests/lift_oracle.py).
//
// The same front-to-back compositing as render_rasterize.wgsl (composite.wgsl), on the same
// tile lists and the same pixels per thread (tile_pixels.wgsl), but instead of colours it sums, per Gaussian g,
//   w_in[g]  += alpha T m(p)        w_out[g] += alpha T (1 - m(p))
// over the tile's pixels p, with m the mask value in [0, 1] and alpha T the
// weight the rasteriser blends g with at p (the same rule, included).
// WGSL has no float atomics: each thread's sum over its eight pixels is
// rounded to fixed point (SCALE units per unit weight) and added into a
// workgroup atomic per batch slot; after the batch one thread per slot adds
// the tile's sum into the Gaussian's 64-bit accumulator (acc[4 g + 0..1] =
// w_in low and high words, acc[4 g + 2..3] = w_out), carrying by hand.  A
// tile sums at most 256 pixels of weight <= 1, so SCALE <= 2^24 cannot
// overflow the 32-bit workgroup sums.

//!include common.wgsl
//!include tile_pixels.wgsl
//!include composite.wgsl

struct Params {
    width: u32,
    height: u32,
    tiles_x: u32,
    tile_begin: u32,   // global id of the window's first tile
    num_tiles: u32,    // tiles in the window
    row_base: u32,     // pixel row stored first in the mask (row bands)
    scale: f32,        // fixed-point units per unit of weight
}

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> ranges: array<u32>;
@group(0) @binding(2) var<storage, read> vals: array<u32>;
@group(0) @binding(3) var<storage, read> pos_op: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> conic: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> mask: array<f32>;
@group(0) @binding(6) var<storage, read_write> acc: array<atomic<u32>>;

var<workgroup> s_pos_op: array<vec4<f32>, 256>;
var<workgroup> s_conic: array<vec4<f32>, 256>;
var<workgroup> s_in: array<atomic<u32>, 256>;
var<workgroup> s_out: array<atomic<u32>, 256>;


// 64-bit add of v into acc[i] (low word) and acc[i + 1] (high word).
fn add64(i: u32, v: u32) {
    if (v == 0u) {
        return;
    }
    let old = atomicAdd(&acc[i], v);
    if (old + v < old) {
        atomicAdd(&acc[i + 1u], 1u);
    }
}

@compute @workgroup_size(8, 4)
fn main(@builtin(local_invocation_id) lid: vec3<u32>,
        @builtin(local_invocation_index) tid: u32,
        @builtin(workgroup_id) wid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let wtile = workgroup_index(wid, nwg);
    if (wtile >= p.num_tiles) {
        return;
    }
    let px = tile_pixels(p.tile_begin + wtile, p.tiles_x, lid, p.width, p.height);
    let xs = px.xs;
    let pix_x = px.x;
    let pix_y = px.y;
    let zero = vec4<f32>(0.0);
    var m_in: array<vec4<f32>, GROUPS>;
    var done: array<vec4<bool>, GROUPS>;
    var t_rem: array<vec4<f32>, GROUPS>;
    var all_done = true;
    for (var q = 0u; q < GROUPS; q++) {
        let ys = px.ys[q];
        let inside = px.inside[q];
        var m = zero;
        for (var l = 0u; l < 4u; l++) {
            if (inside[l]) {
                m[l] = clamp(mask[(ys[l] - p.row_base) * p.width + xs[l]], 0.0, 1.0);
            }
        }
        m_in[q] = m;
        done[q] = !inside;
        t_rem[q] = vec4<f32>(1.0);
        all_done = all_done && all(done[q]);
    }
    let start = ranges[2u * wtile];
    let end = ranges[2u * wtile + 1u];

    if (tid == 0u) {
        atomicStore(&done_count, 0u);
    }
    workgroupBarrier();
    if (all_done) {
        atomicAdd(&done_count, 1u);
    }

    let batches = (end - start + BATCH - 1u) / BATCH;
    for (var b = 0u; b < batches; b++) {
        if (tile_finished(tid)) {
            break;
        }
        let first = start + b * BATCH;
        let count = min(BATCH, end - first);
        for (var i = tid; i < BATCH; i += THREADS) {
            atomicStore(&s_in[i], 0u);
            atomicStore(&s_out[i], 0u);
            let k = first + i;
            if (k < end) {
                let g = vals[k];
                s_pos_op[i] = pos_op[g];
                s_conic[i] = conic[g];
            }
        }
        workgroupBarrier();
        if (!all_done) {
            for (var j = 0u; j < count; j++) {
                let po = s_pos_op[j];
                let co = s_conic[j];
                let dx = vec4<f32>(po.x) - pix_x;
                let cxx = -0.5 * co.x * dx * dx;
                let cxy = co.y * dx;
                all_done = true;
                var w_in = 0.0;
                var w_all = 0.0;
                for (var q = 0u; q < GROUPS; q++) {
                    let dy = vec4<f32>(po.y) - pix_y[q];
                    let power = cxx - 0.5 * co.z * dy * dy - cxy * dy;
                    let c = composite(power, po.w, t_rem[q], !done[q]);
                    done[q] = done[q] | c.stop;
                    w_in += dot(c.w, m_in[q]);
                    w_all += dot(c.w, vec4<f32>(1.0));
                    t_rem[q] = select(t_rem[q], c.t_next, c.blend);
                    all_done = all_done && all(done[q]);
                }
                let q_in = u32(round(w_in * p.scale));
                let q_out = u32(round(max(w_all - w_in, 0.0) * p.scale));
                if (q_in != 0u) {
                    atomicAdd(&s_in[j], q_in);
                }
                if (q_out != 0u) {
                    atomicAdd(&s_out[j], q_out);
                }
                if (all_done) {
                    break;
                }
            }
            if (all_done) {
                atomicAdd(&done_count, 1u);
            }
        }
        workgroupBarrier();
        for (var i = tid; i < count; i += THREADS) {
            let g = vals[first + i];
            add64(4u * g, atomicLoad(&s_in[i]));
            add64(4u * g + 2u, atomicLoad(&s_out[i]));
        }
    }
}
