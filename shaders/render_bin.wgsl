// Binning of projected Gaussians into 16x16 tiles, in depth order.
//
// The host processes the image's tiles in windows of consecutive tile ids
// [tile_begin, tile_end) (row-major tile ids: id = ty * tiles_x + tx) so that
// each window's key list fits one storage binding.  For depth-sorted position
// j (Gaussian order[j]):
//
//   count: counts[j] = number of tiles of the Gaussian's rectangle inside the
//          window that it can affect (see below)
//   emit:  after an exclusive scan of counts into offsets, writes one key per
//          touched tile: keys[offsets[j] + k] = tile id - tile_begin and
//          vals[offsets[j] + k] = Gaussian index.
//
// Emitting in depth order and then stably sorting by tile id leaves each
// tile's Gaussians sorted front to back.
//
// Only tiles the Gaussian can affect get a key: a tile of the rectangle is
// skipped when the minimum over its pixel centres of
// q = 0.5 (a dx^2 + c dy^2) + b dx dy exceeds log(255 opacity), i.e. when
// alpha < 1/255 at every pixel of the tile, so no pixel changes.

//!include common.wgsl

struct Params {
    n: u32,           // Gaussians (length of `order`)
    tiles_x: u32,
    tile_begin: u32,
    tile_end: u32,
}

// Invocations per workgroup, one per element; the host reads it (gpu.shaders.workgroup_threads).
const WG: u32 = 256u;

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> order: array<u32>;
@group(0) @binding(2) var<storage, read> rect: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> counts: array<u32>;
@group(0) @binding(4) var<storage, read_write> keys: array<u32>;
@group(0) @binding(5) var<storage, read_write> vals: array<u32>;
@group(0) @binding(6) var<storage, read> pos_op: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> conic: array<vec4<f32>>;

// Set by the host from r360gpu/render/conventions.py (SHADER_CONSTANTS).
override TILE: f32;
override ALPHA_MIN: f32;
// Safety margin on the threshold against float rounding (q is O(10)).
const Q_MARGIN: f32 = 0.001;

struct Footprint {
    mean: vec2<f32>,
    conic: vec3<f32>,
    q_max: f32,  // q beyond which alpha < 1/255
}

fn footprint(g: u32) -> Footprint {
    let po = pos_op[g];
    var f: Footprint;
    f.mean = po.xy;
    f.conic = conic[g].xyz;
    f.q_max = log(po.w / ALPHA_MIN) + Q_MARGIN;
    return f;
}

// Minimum of q over the segment u = fixed, v in [v0, v1] (u, v: offsets along
// the first / second axis with quadratic coefficients au, b, av).
fn edge_min(u: f32, v0: f32, v1: f32, au: f32, b: f32, av: f32) -> f32 {
    let v = clamp(-b * u / av, v0, v1);
    return 0.5 * (au * u * u + av * v * v) + b * u * v;
}

// Whether any pixel centre of tile (tx, ty) has q <= q_max.
fn tile_hit(f: Footprint, tx: u32, ty: u32) -> bool {
    let x0 = f32(tx) * TILE - f.mean.x;
    let y0 = f32(ty) * TILE - f.mean.y;
    let x1 = x0 + TILE - 1.0;
    let y1 = y0 + TILE - 1.0;
    if (x0 <= 0.0 && x1 >= 0.0 && y0 <= 0.0 && y1 >= 0.0) {
        return true;  // the mean's pixel box
    }
    let a = f.conic.x;
    let b = f.conic.y;
    let c = f.conic.z;
    let q = min(min(edge_min(x0, y0, y1, a, b, c), edge_min(x1, y0, y1, a, b, c)),
                min(edge_min(y0, x0, x1, c, b, a), edge_min(y1, x0, x1, c, b, a)));
    return q <= f.q_max;
}

// Rows of the rectangle that can hold tiles of the window.
fn row_span(r: vec4<u32>) -> vec2<u32> {
    let first = max(r.y, p.tile_begin / p.tiles_x);
    let last = min(r.w, (p.tile_end + p.tiles_x - 1u) / p.tiles_x);
    return vec2<u32>(first, max(first, last));
}

// Tile ids of row `row` of the rectangle, clipped to the window: [begin, end).
fn row_ids(r: vec4<u32>, row: u32) -> vec2<u32> {
    let begin = max(row * p.tiles_x + r.x, p.tile_begin);
    let end = min(row * p.tiles_x + r.z, p.tile_end);
    return vec2<u32>(begin, max(begin, end));
}

@compute @workgroup_size(WG)
fn count(@builtin(local_invocation_index) lidx: u32,
         @builtin(workgroup_id) wid: vec3<u32>,
         @builtin(num_workgroups) nwg: vec3<u32>) {
    let j = workgroup_index(wid, nwg) * WG + lidx;
    if (j >= p.n) {
        return;
    }
    let g = order[j];
    let r = rect[g];
    let rows = row_span(r);
    var c = 0u;
    if (rows.y > rows.x) {
        let f = footprint(g);
        for (var row = rows.x; row < rows.y; row++) {
            let ids = row_ids(r, row);
            for (var id = ids.x; id < ids.y; id++) {
                c += select(0u, 1u, tile_hit(f, id - row * p.tiles_x, row));
            }
        }
    }
    counts[j] = c;
}

@compute @workgroup_size(WG)
fn emit(@builtin(local_invocation_index) lidx: u32,
        @builtin(workgroup_id) wid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let j = workgroup_index(wid, nwg) * WG + lidx;
    if (j >= p.n) {
        return;
    }
    let g = order[j];
    let r = rect[g];
    let rows = row_span(r);
    var o = counts[j];
    if (rows.y <= rows.x) {
        return;
    }
    let f = footprint(g);
    for (var row = rows.x; row < rows.y; row++) {
        let ids = row_ids(r, row);
        for (var id = ids.x; id < ids.y; id++) {
            if (tile_hit(f, id - row * p.tiles_x, row)) {
                keys[o] = id - p.tile_begin;
                vals[o] = g;
                o += 1u;
            }
        }
    }
}
