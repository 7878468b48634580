"""A stand-in for the few torch calls of the public Remove360 evaluation modules.

Used ONLY by bench/public_peer/run_public_eval.py, which copies this file into
a temporary folder as ``torch/__init__.py`` (plus ``torch/nn/functional.py``)
when the real torch is not installed, so that the public modules can run
unchanged in a throwaway environment.  It is never imported by r360gpu or its
tests.

What the public modules use (commit dd0aad8): ``torch.from_numpy``,
``Tensor.unsqueeze/squeeze/float/long/int/to(torch.uint8)/numpy/shape``,
comparisons, ``*`` and ``&``, ``.sum().item()``, ``torch.logical_and/or``,
``torch.zeros_like`` and ``F.interpolate(mode="nearest" | "nearest-exact")``
on 4-D (1, 1, H, W) tensors.  Nearest index rules are those of torch's CPU
kernel (aten/src/ATen/native/UpSample.h): ``nearest``: same size -> identity,
exact 2x -> ``dst >> 1``, else ``min(floor(dst * s), in - 1)`` with
``s = float(in) / out`` in float32; ``nearest-exact``:
``min(floor((dst + 0.5) * s), in - 1)``.
"""
import numpy as _np

uint8 = _np.uint8
float32 = _np.float32
int64 = _np.int64
int32 = _np.int32
bool = _np.bool_


def _arr(x):
    return x.a if isinstance(x, Tensor) else x


class Tensor:
    def __init__(self, a):
        self.a = _np.asarray(a)

    shape = property(lambda self: tuple(self.a.shape))

    def unsqueeze(self, d):
        return Tensor(_np.expand_dims(self.a, d))

    def squeeze(self):
        return Tensor(_np.squeeze(self.a))

    def float(self):
        return Tensor(self.a.astype(_np.float32))

    def long(self):
        return Tensor(self.a.astype(_np.int64))

    def int(self):
        return Tensor(self.a.astype(_np.int32))

    def to(self, dtype):
        return Tensor(self.a.astype(dtype))

    def numpy(self):
        return self.a

    def sum(self):
        return Tensor(self.a.sum())

    def item(self):
        return self.a.item()

    def __getitem__(self, i):
        return Tensor(self.a[i])

    def __len__(self):
        return len(self.a)

    def __gt__(self, o):
        return Tensor(self.a > _arr(o))

    def __lt__(self, o):
        return Tensor(self.a < _arr(o))

    def __ge__(self, o):
        return Tensor(self.a >= _arr(o))

    def __eq__(self, o):
        return Tensor(self.a == _arr(o))

    def __ne__(self, o):
        return Tensor(self.a != _arr(o))

    def __and__(self, o):
        return Tensor(self.a & _arr(o))

    def __or__(self, o):
        return Tensor(self.a | _arr(o))

    def __mul__(self, o):
        a, b = self.a, _np.asarray(_arr(o))
        if a.dtype == _np.bool_ and b.dtype == _np.bool_:
            return Tensor(a & b)  # torch: bool * bool stays bool
        return Tensor(a * b)

    def __sub__(self, o):
        return Tensor(self.a - _arr(o))

    def __float__(self):
        return float(self.a)


def from_numpy(a):
    return Tensor(a)


def zeros_like(t):
    return Tensor(_np.zeros_like(_arr(t)))


def logical_and(a, b):
    return Tensor(_np.logical_and(_arr(a), _arr(b)))


def logical_or(a, b):
    return Tensor(_np.logical_or(_arr(a), _arr(b)))


def _index(out_size, in_size, exact):
    # Written here rather than imported from r360gpu.metrics.compat_public on purpose: the compat
    # fixture's expected numbers must come from code independent of the implementation they check.
    dst = _np.arange(out_size)
    if out_size == in_size:
        return dst
    if not exact and out_size == 2 * in_size:
        return dst >> 1
    s = _np.float32(_np.float32(in_size) / _np.float32(out_size))
    if exact:
        src = _np.floor(((dst + 0.5) * _np.float64(s)).astype(_np.float32))
    else:
        src = _np.floor(dst.astype(_np.float32) * s)
    return _np.minimum(src.astype(_np.int64), in_size - 1)


def _interpolate(t, size=None, mode="nearest", **_):
    a = _arr(t)
    assert a.ndim == 4 and mode in ("nearest", "nearest-exact"), (a.shape, mode)
    h, w = size
    r = _index(h, a.shape[2], mode == "nearest-exact")
    c = _index(w, a.shape[3], mode == "nearest-exact")
    return Tensor(a[:, :, r[:, None], c[None, :]])
