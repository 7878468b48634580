// 3DGS projection: one thread per Gaussian (INRIA 3DGS preprocess).
//
// For Gaussian i (global index base + local index) writes
//   pos_op[i] = (u, v, z, opacity)   opacity times the antialiasing compensation
//                                    when p.antialiased; u, v: projected mean in pixel-index
//                                    coordinates (pixel (x, y) has its centre at
//                                    (x, y), i.e. u = fx * X / Z + cx - 0.5);
//                                    z: camera-space depth
//   conic[i]  = (a, b, c, 0)         inverse 2D covariance [[a, b], [b, c]]
//   rgb[i]    = (r, g, b, 0)         max(SH(dir) + 0.5, 0)
//   rect[i]   = (x0, y0, x1, y1)     tiles [x0, x1) x [y0, y1) touched; all 0 if culled
//   depth_key[i] = bitcast<u32>(z)   (z > 0 so the bits order like the floats);
//                  0xffffffff if culled
//   idx[i] = i
// and adds each touched tile row's tile count to row_counts[row] (the host
// plans key windows from them).
//
// Culling: z <= near, a singular 2D covariance, (compensated) opacity below
// 1/255 (can never reach the blend threshold), or an empty tile rectangle.  The tile rectangle
// is INRIA's 3-sigma rectangle intersected with the tiles that hold a pixel
// within the opacity-aware radius sqrt(2 lambda1 log(255 opacity)): fewer keys,
// identical images, because every dropped pixel-Gaussian pair is below the
// blend threshold.

//!include common.wgsl

struct Params {
    r00: f32, r01: f32, r02: f32,
    r10: f32, r11: f32, r12: f32,
    r20: f32, r21: f32, r22: f32,
    tx: f32, ty: f32, tz: f32,
    cam_x: f32, cam_y: f32, cam_z: f32,
    fx: f32, fy: f32, cx: f32, cy: f32,
    lim_x_neg: f32, lim_x_pos: f32, lim_y_neg: f32, lim_y_pos: f32,
    near: f32,
    tiles_x: u32, tiles_y: u32,
    n: u32,           // Gaussians in this chunk
    base: u32,        // global index of the chunk's first Gaussian
    sh_degree: u32,   // degree used for colour (<= stored degree)
    sh_stride: u32,   // floats per Gaussian in `sh` (3 * K)
    antialiased: u32, // 1: opacity *= sqrt(max(AA_MIN_RATIO, det / det_blurred))
}

// Set by the host from r360gpu/render/conventions.py (SHADER_CONSTANTS).
override TILE: f32;
override COV2D_BLUR: f32;
override ALPHA_MIN: f32;
override AA_MIN_RATIO: f32;
override SIGMA_EXTENT: f32;
// Margin on log(255 * opacity) so that float rounding cannot drop a pixel
// whose alpha is at the blend threshold.
const RADIUS_LOG_MARGIN: f32 = 0.001;

const SH_C0: f32 = 0.28209479177387814;
const SH_C1: f32 = 0.4886025119029199;
const SH_C2_0: f32 = 1.0925484305920792;
const SH_C2_1: f32 = -1.0925484305920792;
const SH_C2_2: f32 = 0.31539156525252005;
const SH_C2_3: f32 = -1.0925484305920792;
const SH_C2_4: f32 = 0.5462742152960396;
const SH_C3_0: f32 = -0.5900435899266435;
const SH_C3_1: f32 = 2.890611442640554;
const SH_C3_2: f32 = -0.4570457994644658;
const SH_C3_3: f32 = 0.3731763325901154;
const SH_C3_4: f32 = -0.4570457994644658;
const SH_C3_5: f32 = 1.445305721320277;
const SH_C3_6: f32 = -0.5900435899266435;

// Invocations per workgroup, one per element; the host reads it (gpu.shaders.workgroup_threads).
const WG: u32 = 256u;

@group(0) @binding(0) var<uniform> p: Params;
// Per Gaussian: (mx, my, mz, opacity), (sx, sy, sz, 0), (qw, qx, qy, qz).
@group(0) @binding(1) var<storage, read> params: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> sh: array<f32>;
@group(0) @binding(3) var<storage, read_write> pos_op: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> conic: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> rgb: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> rect: array<vec4<u32>>;
@group(0) @binding(7) var<storage, read_write> depth_key: array<u32>;
@group(0) @binding(8) var<storage, read_write> idx: array<u32>;
@group(0) @binding(9) var<storage, read_write> row_counts: array<atomic<u32>>;

fn sh_coeff(i: u32, k: u32) -> vec3<f32> {
    let o = i * p.sh_stride + 3u * k;
    return vec3<f32>(sh[o], sh[o + 1u], sh[o + 2u]);
}

fn sh_color(i: u32, mean: vec3<f32>) -> vec3<f32> {
    var dir = mean - vec3<f32>(p.cam_x, p.cam_y, p.cam_z);
    let len = length(dir);
    if (len > 0.0) {
        dir = dir / len;
    } else {
        dir = vec3<f32>(0.0);
    }
    var c = SH_C0 * sh_coeff(i, 0u);
    if (p.sh_degree >= 1u) {
        let x = dir.x;
        let y = dir.y;
        let z = dir.z;
        c += -SH_C1 * y * sh_coeff(i, 1u) + SH_C1 * z * sh_coeff(i, 2u) - SH_C1 * x * sh_coeff(i, 3u);
        if (p.sh_degree >= 2u) {
            let xx = x * x;
            let yy = y * y;
            let zz = z * z;
            let xy = x * y;
            let yz = y * z;
            let xz = x * z;
            c += SH_C2_0 * xy * sh_coeff(i, 4u)
               + SH_C2_1 * yz * sh_coeff(i, 5u)
               + SH_C2_2 * (2.0 * zz - xx - yy) * sh_coeff(i, 6u)
               + SH_C2_3 * xz * sh_coeff(i, 7u)
               + SH_C2_4 * (xx - yy) * sh_coeff(i, 8u);
            if (p.sh_degree >= 3u) {
                c += SH_C3_0 * y * (3.0 * xx - yy) * sh_coeff(i, 9u)
                   + SH_C3_1 * xy * z * sh_coeff(i, 10u)
                   + SH_C3_2 * y * (4.0 * zz - xx - yy) * sh_coeff(i, 11u)
                   + SH_C3_3 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy) * sh_coeff(i, 12u)
                   + SH_C3_4 * x * (4.0 * zz - xx - yy) * sh_coeff(i, 13u)
                   + SH_C3_5 * z * (xx - yy) * sh_coeff(i, 14u)
                   + SH_C3_6 * x * (xx - 3.0 * yy) * sh_coeff(i, 15u);
            }
        }
    }
    return max(c + vec3<f32>(0.5), vec3<f32>(0.0));
}

fn cull(g: u32) {
    pos_op[g] = vec4<f32>(0.0);
    conic[g] = vec4<f32>(0.0);
    rgb[g] = vec4<f32>(0.0);
    rect[g] = vec4<u32>(0u);
    depth_key[g] = 0xffffffffu;
}

@compute @workgroup_size(WG)
fn main(@builtin(local_invocation_index) lidx: u32,
        @builtin(workgroup_id) wid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = workgroup_index(wid, nwg) * WG + lidx;
    if (i >= p.n) {
        return;
    }
    let g = p.base + i;
    idx[g] = g;
    let a = params[3u * i];
    let mean = a.xyz;
    let opacity = a.w;
    // World-to-camera rotation, rows.
    let w0 = vec3<f32>(p.r00, p.r01, p.r02);
    let w1 = vec3<f32>(p.r10, p.r11, p.r12);
    let w2 = vec3<f32>(p.r20, p.r21, p.r22);
    let t = vec3<f32>(dot(w0, mean) + p.tx, dot(w1, mean) + p.ty, dot(w2, mean) + p.tz);
    if (t.z <= p.near || opacity < ALPHA_MIN) {
        cull(g);
        return;
    }

    // 3D covariance Sigma = M M^T with M = R(q) S.
    let s = params[3u * i + 1u].xyz;
    var q = params[3u * i + 2u];
    q = q / length(q);
    let qw = q.x;
    let qx = q.y;
    let qy = q.z;
    let qz = q.w;
    // Columns of R(q) scaled by s.
    let m0 = s.x * vec3<f32>(1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy + qw * qz), 2.0 * (qx * qz - qw * qy));
    let m1 = s.y * vec3<f32>(2.0 * (qx * qy - qw * qz), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz + qw * qx));
    let m2 = s.z * vec3<f32>(2.0 * (qx * qz + qw * qy), 2.0 * (qy * qz - qw * qx), 1.0 - 2.0 * (qx * qx + qy * qy));

    // EWA: Jacobian of the perspective map at the mean, with the mean's
    // direction clamped to a guarded frustum (as INRIA/gsplat) so Gaussians
    // far outside the view do not get degenerate footprints.
    let inv_z = 1.0 / t.z;
    let txc = clamp(t.x * inv_z, -p.lim_x_neg, p.lim_x_pos) * t.z;
    let tyc = clamp(t.y * inv_z, -p.lim_y_neg, p.lim_y_pos) * t.z;
    let j0 = vec3<f32>(p.fx * inv_z, 0.0, -p.fx * txc * inv_z * inv_z);
    let j1 = vec3<f32>(0.0, p.fy * inv_z, -p.fy * tyc * inv_z * inv_z);
    // T = J W (2x3) with W the world-to-camera rotation.
    let t0 = j0.x * w0 + j0.y * w1 + j0.z * w2;
    let t1 = j1.x * w0 + j1.y * w1 + j1.z * w2;
    // cov2 = (T M)(T M)^T
    let u0 = vec3<f32>(dot(t0, m0), dot(t0, m1), dot(t0, m2));
    let u1 = vec3<f32>(dot(t1, m0), dot(t1, m1), dot(t1, m2));
    let ca0 = dot(u0, u0);
    let cb = dot(u0, u1);
    let cc0 = dot(u1, u1);
    let ca = ca0 + COV2D_BLUR;
    let cc = cc0 + COV2D_BLUR;
    let det = ca * cc - cb * cb;
    var opacity_eff = opacity;
    if (p.antialiased != 0u) {
        // gsplat's add_blur / INRIA's h_convolution_scaling: the blur's added
        // area is taken back from the opacity.
        opacity_eff = opacity * sqrt(max(AA_MIN_RATIO, (ca0 * cc0 - cb * cb) / det));
    }
    if (!(det > 0.0) || opacity_eff < ALPHA_MIN) {
        cull(g);
        return;
    }
    let inv_det = 1.0 / det;
    let mid = 0.5 * (ca + cc);
    let lambda1 = mid + sqrt(max(0.1, mid * mid - det));
    let px = p.fx * t.x * inv_z + p.cx - 0.5;
    let py = p.fy * t.y * inv_z + p.cy - 0.5;
    // INRIA's rectangle: radius ceil(3 sigma), tiles [floor((p - r) / 16),
    // floor((p + r + 15) / 16)).  (Its upper end can miss a tile the radius
    // reaches; kept as is so images match INRIA's.)
    let r3 = ceil(SIGMA_EXTENT * sqrt(lambda1));
    var lo = floor((vec2<f32>(px, py) - r3) / TILE);
    var hi = floor((vec2<f32>(px, py) + r3 + TILE - 1.0) / TILE);
    // Intersect with the tiles holding a pixel within the opacity-aware radius;
    // beyond it opacity * exp(-power) < 1/255, so no pixel changes.
    let r_alpha = sqrt(2.0 * lambda1 * max(log(opacity_eff / ALPHA_MIN) + RADIUS_LOG_MARGIN, 0.0));
    lo = max(lo, floor(ceil(vec2<f32>(px, py) - r_alpha) / TILE));
    hi = min(hi, floor(floor(vec2<f32>(px, py) + r_alpha) / TILE) + 1.0);
    // Float clamps before the integer conversion keep far-away means in range.
    let grid = vec2<f32>(f32(p.tiles_x), f32(p.tiles_y));
    let x0 = u32(clamp(lo.x, 0.0, grid.x));
    let y0 = u32(clamp(lo.y, 0.0, grid.y));
    let x1 = u32(clamp(hi.x, 0.0, grid.x));
    let y1 = u32(clamp(hi.y, 0.0, grid.y));
    if (x1 <= x0 || y1 <= y0) {
        cull(g);
        return;
    }
    pos_op[g] = vec4<f32>(px, py, t.z, opacity_eff);
    conic[g] = vec4<f32>(cc * inv_det, -cb * inv_det, ca * inv_det, 0.0);
    rgb[g] = vec4<f32>(sh_color(i, mean), 0.0);
    rect[g] = vec4<u32>(x0, y0, x1, y1);
    depth_key[g] = bitcast<u32>(t.z);
    for (var row = y0; row < y1; row++) {
        atomicAdd(&row_counts[row], x1 - x0);
    }
}
