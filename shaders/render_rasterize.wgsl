// Front-to-back alpha compositing of one 16x16 tile per workgroup (INRIA 3DGS
// forward pass), plus expected and median depth.
//
// The tile's pixels, threads and batches are tile_pixels.wgsl's; the compositing rule (alpha
// clamps, the transmittance stop, the weight w = alpha T) is composite.wgsl's.  Per pixel and Gaussian:
//   power = -0.5 (a dx^2 + c dy^2) - b dx dy      (d = mean - pixel)
//   where it blends: colour += w * rgb, sum_w += w, sum_wz += w * z
//   the median depth is z of the first blended Gaussian with T * (1 - alpha) <= MEDIAN_T
// Outputs (each a separate plane of f32, row-major, width floats per row, its
// first row pixel row p.row_base: the host renders images beyond one binding
// in bands of whole tile rows):
//   r, g, b = colour + T * background;  alpha = 1 - T;
//   depth = sum_wz / sum_w and median depth, both 0 where alpha < min_alpha.
// The workgroup stops early once every pixel is finished.  work[2t], work[2t+1]
// count the tile's evaluated and blended pixel-Gaussian pairs (for benchmarks).

//!include common.wgsl
//!include tile_pixels.wgsl
//!include composite.wgsl

struct Params {
    width: u32,
    height: u32,
    tiles_x: u32,
    tile_begin: u32,   // global id of the window's first tile
    num_tiles: u32,    // tiles in the window
    bg_r: f32,
    bg_g: f32,
    bg_b: f32,
    min_alpha: f32,    // coverage threshold for the depth outputs
    row_base: u32,     // pixel row stored first in the output planes (row bands)
}

// Set by the host from r360gpu/render/conventions.py (SHADER_CONSTANTS).
override MEDIAN_T: f32;

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> ranges: array<u32>;
@group(0) @binding(2) var<storage, read> vals: array<u32>;
@group(0) @binding(3) var<storage, read> pos_op: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> conic: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> rgb: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> out_r: array<f32>;
@group(0) @binding(7) var<storage, read_write> out_g: array<f32>;
@group(0) @binding(8) var<storage, read_write> out_b: array<f32>;
@group(0) @binding(9) var<storage, read_write> out_alpha: array<f32>;
@group(0) @binding(10) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(11) var<storage, read_write> out_median: array<f32>;
// Work counters per window tile: (pixel-Gaussian pairs evaluated, pairs blended).
@group(0) @binding(12) var<storage, read_write> work: array<u32>;

var<workgroup> s_pos_op: array<vec4<f32>, 256>;
var<workgroup> s_conic: array<vec4<f32>, 256>;
var<workgroup> s_rgb: array<vec4<f32>, 256>;
var<workgroup> evaluated_count: atomic<u32>;
var<workgroup> blended_count: atomic<u32>;


fn count_true(v: vec4<bool>) -> u32 {
    return dot(select(vec4<u32>(0u), vec4<u32>(1u), v), vec4<u32>(1u));
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
    let ys = px.ys;
    let pix_y = px.y;
    let inside = px.inside;
    var done: array<vec4<bool>, GROUPS>;
    var all_done = true;
    for (var q = 0u; q < GROUPS; q++) {
        done[q] = !inside[q];
        all_done = all_done && all(done[q]);
    }
    let start = ranges[2u * wtile];
    let end = ranges[2u * wtile + 1u];

    if (tid == 0u) {
        atomicStore(&done_count, 0u);
        atomicStore(&evaluated_count, 0u);
        atomicStore(&blended_count, 0u);
    }
    workgroupBarrier();
    if (all_done) {
        atomicAdd(&done_count, 1u);
    }

    let zero = vec4<f32>(0.0);
    var t_rem: array<vec4<f32>, GROUPS>;
    var col_r: array<vec4<f32>, GROUPS>;
    var col_g: array<vec4<f32>, GROUPS>;
    var col_b: array<vec4<f32>, GROUPS>;
    var sum_w: array<vec4<f32>, GROUPS>;
    var sum_wz: array<vec4<f32>, GROUPS>;
    var median: array<vec4<f32>, GROUPS>;
    var median_found: array<vec4<bool>, GROUPS>;
    for (var q = 0u; q < GROUPS; q++) {
        t_rem[q] = vec4<f32>(1.0);
        col_r[q] = zero;
        col_g[q] = zero;
        col_b[q] = zero;
        sum_w[q] = zero;
        sum_wz[q] = zero;
        median[q] = zero;
        median_found[q] = vec4<bool>(false);
    }
    var evaluated = 0u;
    var blended = 0u;

    let batches = (end - start + BATCH - 1u) / BATCH;
    for (var b = 0u; b < batches; b++) {
        if (tile_finished(tid)) {
            break;
        }
        let first = start + b * BATCH;
        for (var i = tid; i < BATCH; i += THREADS) {
            let k = first + i;
            if (k < end) {
                let g = vals[k];
                s_pos_op[i] = pos_op[g];
                s_conic[i] = conic[g];
                s_rgb[i] = rgb[g];
            }
        }
        workgroupBarrier();
        if (!all_done) {
            let count = min(BATCH, end - first);
            for (var j = 0u; j < count; j++) {
                let po = s_pos_op[j];
                let co = s_conic[j];
                let col = s_rgb[j];
                let dx = vec4<f32>(po.x) - pix_x;
                let cxx = -0.5 * co.x * dx * dx;
                let cxy = co.y * dx;
                all_done = true;
                for (var q = 0u; q < GROUPS; q++) {
                    let dy = vec4<f32>(po.y) - pix_y[q];
                    let power = cxx - 0.5 * co.z * dy * dy - cxy * dy;
                    let live = !done[q];
                    evaluated += count_true(live);
                    let c = composite(power, po.w, t_rem[q], live);
                    done[q] = done[q] | c.stop;
                    let blend = c.blend;
                    let w = c.w;
                    col_r[q] += w * col.x;
                    col_g[q] += w * col.y;
                    col_b[q] += w * col.z;
                    sum_w[q] += w;
                    sum_wz[q] += w * po.z;
                    let first_median = blend & !median_found[q] & (c.t_next <= vec4<f32>(MEDIAN_T));
                    median[q] = select(median[q], vec4<f32>(po.z), first_median);
                    median_found[q] = median_found[q] | first_median;
                    blended += count_true(blend);
                    t_rem[q] = select(t_rem[q], c.t_next, blend);
                    all_done = all_done && all(done[q]);
                }
                if (all_done) {
                    break;
                }
            }
            if (all_done) {
                atomicAdd(&done_count, 1u);
            }
        }
    }

    atomicAdd(&evaluated_count, evaluated);
    atomicAdd(&blended_count, blended);
    workgroupBarrier();
    if (tid == 0u) {
        work[2u * wtile] = atomicLoad(&evaluated_count);
        work[2u * wtile + 1u] = atomicLoad(&blended_count);
    }

    for (var q = 0u; q < GROUPS; q++) {
        let alpha_out = 1.0 - t_rem[q];
        let covered = (alpha_out >= vec4<f32>(p.min_alpha)) & (sum_w[q] > zero);
        let depth = select(zero, sum_wz[q] / select(vec4<f32>(1.0), sum_w[q], sum_w[q] > zero), covered);
        let med = select(zero, median[q], covered);
        for (var l = 0u; l < 4u; l++) {
            if (inside[q][l]) {
                let pi = (ys[q][l] - p.row_base) * p.width + xs[l];
                out_r[pi] = col_r[q][l] + t_rem[q][l] * p.bg_r;
                out_g[pi] = col_g[q][l] + t_rem[q][l] * p.bg_g;
                out_b[pi] = col_b[q][l] + t_rem[q][l] * p.bg_b;
                out_alpha[pi] = alpha_out[l];
                out_depth[pi] = depth[l];
                out_median[pi] = med[l];
            }
        }
    }
}
