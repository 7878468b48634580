// The interface of one pass of the radix sort, shared by its two variants
// (radix_sort.wgsl, radix_sort_blocks.wgsl; pulled in with `//!include radix_pass.wgsl`):
// the uniform parameters, the bindings and the pass's digit of a key.  The host
// (r360gpu.render.sort) binds the same buffers to either variant.

struct Params {
    n: u32,             // elements in the bound input window
    shift: u32,         // bit position of the digit
    digit_bits: u32,    // bits in this pass's digit, 1 to the variant's DIGIT_BITS
    block_base: u32,    // global index of the window's first block
    total_blocks: u32,  // blocks over the whole input
    out_base: u32,      // global position of the bound output window's first element
    out_count: u32,     // elements in the bound output window
    num_blocks: u32,    // blocks in the bound input window
}

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> keys_in: array<u32>;
@group(0) @binding(2) var<storage, read> vals_in: array<u32>;
@group(0) @binding(3) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(4) var<storage, read_write> vals_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> hist: array<u32>;

fn digit_of(key: u32) -> u32 {
    return (key >> p.shift) & ((1u << p.digit_bits) - 1u);
}
