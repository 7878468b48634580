// Helpers shared by the compute kernels (pulled in with `//!include common.wgsl`,
// see r360gpu/gpu/shaders.py).  No entry point, no bindings.

// Linear id of a workgroup in a dispatch folded into x and y
// (GpuContext.grid spreads a 1-D workgroup count over both dimensions).
fn workgroup_index(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wid.x + wid.y * nwg.x;
}
