"""torchvision.ops.boxes as the CPU code path computes it."""
import torch


def box_area(boxes):
    return (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])


def nms(boxes, scores, iou_threshold):
    """torchvision/csrc/ops/cpu/nms_kernel.cpp: scalar_t (float32) arithmetic, stable descending
    sort, suppress when ovr > iou_threshold (compared as a double); inner loop vectorised."""
    import numpy as np

    if boxes.numel() == 0:
        return torch.empty((0,), dtype=torch.int64)
    b = boxes.numpy()
    x1, y1, x2, y2 = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    areas = (x2 - x1) * (y2 - y1)
    order = torch.sort(scores, stable=True, dim=0, descending=True)[1].numpy()
    suppressed = np.zeros(len(order), bool)
    keep = []
    zero = b.dtype.type(0)
    for _i in range(len(order)):
        i = int(order[_i])
        if suppressed[i]:
            continue
        keep.append(i)
        js = order[_i + 1 :]
        js = js[~suppressed[js]]
        if not len(js):
            continue
        w = np.maximum(zero, np.minimum(x2[i], x2[js]) - np.maximum(x1[i], x1[js]))
        h = np.maximum(zero, np.minimum(y2[i], y2[js]) - np.maximum(y1[i], y1[js]))
        inter = w * h
        with np.errstate(invalid="ignore", divide="ignore"):
            ovr = inter / (areas[i] + areas[js] - inter)
        suppressed[js[ovr.astype(np.float64) > float(iou_threshold)]] = True
    return torch.tensor(keep, dtype=torch.int64)


def batched_nms(boxes, scores, idxs, iou_threshold):
    if boxes.numel() > 4000:  # the CPU threshold of torchvision.ops.boxes.batched_nms
        keep_mask = torch.zeros_like(scores, dtype=torch.bool)
        for class_id in torch.unique(idxs):
            curr = torch.where(idxs == class_id)[0]
            keep_mask[curr[nms(boxes[curr], scores[curr], iou_threshold)]] = True
        keep = torch.where(keep_mask)[0]
        return keep[scores[keep].sort(descending=True)[1]]
    if boxes.numel() == 0:
        return torch.empty((0,), dtype=torch.int64)
    offsets = idxs.to(boxes) * (boxes.max() + torch.tensor(1).to(boxes))
    return nms(boxes + offsets[:, None], scores, iou_threshold)


def box_convert(boxes, in_fmt, out_fmt):
    if (in_fmt, out_fmt) != ("cxcywh", "xyxy"):
        raise ValueError(f"the stand-in converts cxcywh to xyxy only, not {in_fmt} to {out_fmt}")
    cx, cy, w, h = boxes.unbind(-1)
    return torch.stack((cx - 0.5 * w, cy - 0.5 * h, cx + 0.5 * w, cy + 0.5 * h), dim=-1)
