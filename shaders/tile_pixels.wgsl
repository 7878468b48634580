// The pixels of a 16x16 tile and the early stop of its workgroup, shared by the passes that walk
// a tile's depth-sorted Gaussians (render_rasterize.wgsl, lift_accumulate.wgsl).
//
// A workgroup of 8x4 threads covers the tile; each thread owns two 2x2 blocks of pixels (each
// held in the lanes of vec4s), 8 rows apart; pixel (x, y) is centred at (x, y) in the
// pixel-index coordinates of render_project.wgsl.  Eight pixels per thread amortise every read
// of a Gaussian, which matters on CPU implementations where per-lane loads dominate (measured on
// lavapipe: one pixel per thread 4.5x slower, 16 pixels per thread 3x slower: registers spill).
// The tile's Gaussians are loaded BATCH at a time into workgroup memory.  The 16x16 tile is
// built into this shape; the host checks TILE == 16.

const GROUPS: u32 = 2u;       // 2x2 pixel blocks per thread
const THREADS: u32 = 32u;     // 8 x (8 / GROUPS), the workgroup size
const GROUP_ROWS: u32 = 8u;   // pixel rows between a thread's blocks
const BATCH: u32 = 256u;      // Gaussians loaded into workgroup memory at a time

// Threads whose pixels are all finished; a snapshot read by every thread at once.
var<workgroup> done_count: atomic<u32>;
var<workgroup> done_snapshot: u32;

struct TilePixels {
    xs: vec4<u32>,                        // the column of each lane (both blocks)
    x: vec4<f32>,                         // the same, as pixel centres
    ys: array<vec4<u32>, GROUPS>,         // the row of each lane, per block
    y: array<vec4<f32>, GROUPS>,
    inside: array<vec4<bool>, GROUPS>,    // lanes inside the image
}

// This thread's pixels of window tile `tile` (tiles_x tiles per row) in a width x height image.
fn tile_pixels(tile: u32, tiles_x: u32, lid: vec3<u32>, width: u32, height: u32) -> TilePixels {
    var t: TilePixels;
    let x0 = (tile % tiles_x) * 16u + 2u * lid.x;
    let y0 = (tile / tiles_x) * 16u + 2u * lid.y;
    t.xs = vec4<u32>(x0, x0 + 1u, x0, x0 + 1u);
    t.x = vec4<f32>(t.xs);
    for (var q = 0u; q < GROUPS; q++) {
        let y = y0 + q * GROUP_ROWS;
        t.ys[q] = vec4<u32>(y, y, y + 1u, y + 1u);
        t.y[q] = vec4<f32>(t.ys[q]);
        t.inside[q] = (t.xs < vec4<u32>(width)) & (t.ys[q] < vec4<u32>(height));
    }
    return t;
}

// Before a batch (uniform control flow): true once every thread has finished its pixels, so
// the workgroup stops loading Gaussians.
fn tile_finished(tid: u32) -> bool {
    workgroupBarrier();
    if (tid == 0u) {
        done_snapshot = atomicLoad(&done_count);
    }
    return workgroupUniformLoad(&done_snapshot) == THREADS;
}
