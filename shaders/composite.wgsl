// The compositing rule, written once: front-to-back alpha blending of one Gaussian over four
// pixels (the lanes of a vec4), as every pass over the depth-sorted tile lists applies it
// (render_rasterize.wgsl blends colour and depth with it, lift_accumulate.wgsl sums its weights).
//
// INRIA 3DGS: alpha = min(ALPHA_MAX, opacity exp(power)); the Gaussian is skipped where power > 0
// or alpha < ALPHA_MIN; a pixel stops, before blending, where T (1 - alpha) < T_MIN; elsewhere it
// blends with weight alpha T, and T becomes T (1 - alpha).  The overrides are set by the host from
// r360gpu/render/conventions.py (COMPOSITE_CONSTANTS).

override ALPHA_MAX: f32;
override ALPHA_MIN: f32;
override T_MIN: f32;

struct Composite {
    w: vec4<f32>,         // alpha T where the Gaussian blends, else 0
    t_next: vec4<f32>,    // T (1 - alpha): the transmittance behind it, where it blends
    blend: vec4<bool>,    // lanes it blends into
    stop: vec4<bool>,     // lanes that finish before it (not blended)
}

// The Gaussian of `opacity` whose exponent at each lane's pixel is `power`, over lanes of
// transmittance `t`; only `live` lanes (not finished) take part.
fn composite(power: vec4<f32>, opacity: f32, t: vec4<f32>, live: vec4<bool>) -> Composite {
    let zero = vec4<f32>(0.0);
    let alpha = min(vec4<f32>(ALPHA_MAX), opacity * exp(power));
    let use_it = live & (power <= zero) & (alpha >= vec4<f32>(ALPHA_MIN));
    var c: Composite;
    c.t_next = t * (1.0 - alpha);
    c.stop = use_it & (c.t_next < vec4<f32>(T_MIN));
    c.blend = use_it & !c.stop;
    c.w = select(zero, alpha * t, c.blend);
    return c;
}
