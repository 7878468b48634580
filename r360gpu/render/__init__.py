"""3DGS renderer: project -> bin -> sort -> tile ranges -> rasterise (WGSL kernels)."""
