// Inclusive scan of one value per thread across a workgroup, for
// prefix_sum.wgsl and radix_sort.wgsl (pulled in with
// `//!include workgroup_scan.wgsl`, see r360gpu/gpu/shaders.py).
//
// A value is a ScanValue: eight u32 lanes (two vec4), added lane by lane
// (radix_sort packs its 16 digit counters into them; prefix_sum uses lane 0).
// Two serial levels, SCAN_SEG segments of SCAN_SEG threads and then the
// segment totals, need three barriers where a log-step scan needs up to
// sixteen; on CPU implementations, which run a workgroup's SIMD slices as
// coroutines, barriers dominate.  The workgroup has SCAN_SEG * SCAN_SEG
// threads (the pipeline sets SCAN_SEG: 8 for 64 threads, 16 for 256).
// Every thread must call workgroup_scan.

override SCAN_SEG: u32;

struct ScanValue {
    lo: vec4<u32>,
    hi: vec4<u32>,
}

var<workgroup> scan_lo: array<vec4<u32>, 256>;
var<workgroup> scan_hi: array<vec4<u32>, 256>;
var<workgroup> scan_seg_lo: array<vec4<u32>, 16>;
var<workgroup> scan_seg_hi: array<vec4<u32>, 16>;

fn workgroup_scan(tid: u32, own: ScanValue) -> ScanValue {
    scan_lo[tid] = own.lo;
    scan_hi[tid] = own.hi;
    workgroupBarrier();
    if (tid < SCAN_SEG) {
        var lo = vec4<u32>(0u);
        var hi = vec4<u32>(0u);
        for (var i = SCAN_SEG * tid; i < SCAN_SEG * tid + SCAN_SEG; i++) {
            lo += scan_lo[i];
            hi += scan_hi[i];
            scan_lo[i] = lo;
            scan_hi[i] = hi;
        }
        scan_seg_lo[tid] = lo;
        scan_seg_hi[tid] = hi;
    }
    workgroupBarrier();
    if (tid == 0u) {
        var lo = vec4<u32>(0u);
        var hi = vec4<u32>(0u);
        for (var i = 0u; i < SCAN_SEG; i++) {
            let l = scan_seg_lo[i];
            let h = scan_seg_hi[i];
            scan_seg_lo[i] = lo;
            scan_seg_hi[i] = hi;
            lo += l;
            hi += h;
        }
    }
    workgroupBarrier();
    var out: ScanValue;
    out.lo = scan_lo[tid] + scan_seg_lo[tid / SCAN_SEG];
    out.hi = scan_hi[tid] + scan_seg_hi[tid / SCAN_SEG];
    return out;
}
