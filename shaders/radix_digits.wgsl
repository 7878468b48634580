// Packed counters of 4-bit radix digits (16 buckets), shared by radix_sort.wgsl
// and radix_sort_blocks.wgsl (pulled in with `//!include radix_digits.wgsl`).
//
// A thread counts its own items in 8-bit fields of a vec4 (digit d in component
// d / 4, bits 8 * (d % 4)): registers, no dynamically indexed array.  Across
// threads the counts are widened to 16-bit fields in a Packed value (lo: digits
// 0-7, hi: digits 8-15, two per word), which workgroup_scan.wgsl scans lane by
// lane.

//!include workgroup_scan.wgsl
alias Packed = ScanValue;

// 8-bit fields -> 16-bit fields.
fn widen(c: vec4<u32>) -> Packed {
    var out: Packed;
    for (var w = 0u; w < 4u; w++) {
        // Word w of lo holds digits 2w, 2w + 1; digit d sits in c[d / 4] at 8 * (d % 4).
        let d = 2u * w;
        out.lo[w] = ((c[d >> 2u] >> (8u * (d & 3u))) & 255u) | (((c[(d + 1u) >> 2u] >> (8u * ((d + 1u) & 3u))) & 255u) << 16u);
        let e = d + 8u;
        out.hi[w] = ((c[e >> 2u] >> (8u * (e & 3u))) & 255u) | (((c[(e + 1u) >> 2u] >> (8u * ((e + 1u) & 3u))) & 255u) << 16u);
    }
    return out;
}

fn field16(v: Packed, d: u32) -> u32 {
    let word = select(v.lo, v.hi, d >= 8u)[(d >> 1u) & 3u];
    return (word >> (16u * (d & 1u))) & 0xffffu;
}

// Adds one to digit d's 8-bit field; returns the field's old value.
fn bump(c: ptr<function, vec4<u32>>, d: u32) -> u32 {
    let sh = 8u * (d & 3u);
    let w = d >> 2u;
    let old = ((*c)[w] >> sh) & 255u;
    (*c)[w] += 1u << sh;
    return old;
}
