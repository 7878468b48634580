"""The numpy oracles of the GPU kernels live beside the kernels
(:mod:`r360gpu.kernels.reference`) so ``r360gpu doctor`` can use them too."""
from r360gpu.kernels.reference import depth_change_reference as depth_change_oracle  # noqa: F401
from r360gpu.kernels.reference import mask_iou_reference as mask_iou_oracle  # noqa: F401
from r360gpu.kernels.reference import no_depth_in_mask_reference as no_depth_oracle  # noqa: F401
