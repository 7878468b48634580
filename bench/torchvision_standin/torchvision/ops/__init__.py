from .boxes import batched_nms, box_area, box_convert, nms  # noqa: F401
