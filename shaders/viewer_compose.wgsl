// Viewer composition: draws one or two panel pictures into the window.
//
// Host side and conventions: viewer/compose.py.
// Each picture is packed rgba8 (one u32 per pixel, row-major, sRGB-encoded),
// drawn into its rectangle (x0, y0, w, h) in framebuffer pixels with bilinear
// filtering between pixel centres (at 1:1 scale every fragment hits a pixel
// centre, so the picture is copied exactly).  Outside every rectangle the
// letterbox colour is drawn.
//   mode 0: picture A only       mode 1: side by side (A in rect_a, B in rect_b)
//   mode 2: wipe (both pictures in rect_a; A left of wipe_x, B right of it,
//           with a WIPE_LINE_PX-wide line on the split)
// srgb_target = 1 when the target format is *-srgb: the hardware encodes,
// so the sRGB values are decoded to linear first.

struct Params {
    rect_a: vec4<f32>,
    rect_b: vec4<f32>,
    size_a: vec2<u32>,
    size_b: vec2<u32>,
    mode: u32,
    srgb_target: u32,
    wipe_x: f32,
    pad0: f32,
    letterbox: vec4<f32>,
};

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> pic_a: array<u32>;
@group(0) @binding(2) var<storage, read> pic_b: array<u32>;

const WIPE_LINE_PX: f32 = 2.0;
const WIPE_RGB: vec3<f32> = vec3<f32>(1.0, 1.0, 1.0);

struct VsOut {
    @builtin(position) pos: vec4<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    // One triangle covering the whole viewport.
    let x = f32((vi << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vi & 2u) * 2.0 - 1.0;
    var o: VsOut;
    o.pos = vec4<f32>(x, y, 0.0, 1.0);
    return o;
}

fn texel(b: u32, x: i32, y: i32, size: vec2<u32>) -> vec3<f32> {
    let xc = u32(clamp(x, 0, i32(size.x) - 1));
    let yc = u32(clamp(y, 0, i32(size.y) - 1));
    let i = yc * size.x + xc;
    if (b == 0u) {
        return unpack4x8unorm(pic_a[i]).rgb;
    }
    return unpack4x8unorm(pic_b[i]).rgb;
}

// Bilinear sample of picture b at framebuffer point p inside rect r; a
// missing picture (size 0) shows the letterbox colour.
fn sample(b: u32, p: vec2<f32>, r: vec4<f32>, size: vec2<u32>) -> vec3<f32> {
    if (size.x == 0u || size.y == 0u) {
        return P.letterbox.rgb;
    }
    let uv = (p - r.xy) / r.zw * vec2<f32>(size) - vec2<f32>(0.5);
    let f = floor(uv);
    let t = uv - f;
    let x0 = i32(f.x);
    let y0 = i32(f.y);
    let c00 = texel(b, x0, y0, size);
    let c10 = texel(b, x0 + 1, y0, size);
    let c01 = texel(b, x0, y0 + 1, size);
    let c11 = texel(b, x0 + 1, y0 + 1, size);
    return mix(mix(c00, c10, t.x), mix(c01, c11, t.x), t.y);
}

fn inside(p: vec2<f32>, r: vec4<f32>) -> bool {
    return p.x >= r.x && p.y >= r.y && p.x < r.x + r.z && p.y < r.y + r.w;
}

fn to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + vec3<f32>(0.055)) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

@fragment
fn fs_main(v: VsOut) -> @location(0) vec4<f32> {
    let p = v.pos.xy;
    var c = P.letterbox.rgb;
    if (P.mode == 1u) {
        if (inside(p, P.rect_a)) {
            c = sample(0u, p, P.rect_a, P.size_a);
        } else if (inside(p, P.rect_b)) {
            c = sample(1u, p, P.rect_b, P.size_b);
        }
    } else if (inside(p, P.rect_a)) {
        if (P.mode == 2u && p.x >= P.wipe_x) {
            c = sample(1u, p, P.rect_a, P.size_b);
        } else {
            c = sample(0u, p, P.rect_a, P.size_a);
        }
        if (P.mode == 2u && abs(p.x - P.wipe_x) < WIPE_LINE_PX * 0.5) {
            c = WIPE_RGB;
        }
    }
    if (P.srgb_target == 1u) {
        c = to_linear(c);
    }
    return vec4<f32>(c, 1.0);
}
