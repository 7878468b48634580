"""The part of torch the public Remove360 evaluation modules use, on numpy.

Only for bench/bench_vs_public.py, which runs those modules (fetched at run
time) on a machine without torch.  Their use is ``from_numpy``, dtype casts,
``unsqueeze``/``squeeze``, comparisons and logic, ``sum().item()``,
``zeros_like`` and nearest ``interpolate``; each is the numpy operation with
torch's semantics for those calls (dtype casts truncate like torch's).
"""
from __future__ import annotations

import numpy as np

uint8 = np.uint8
float32 = np.float32
int32 = np.int32
int64 = np.int64
long = np.int64
bool = np.bool_  # noqa: A001 - torch's name


class Tensor(np.ndarray):
    """A numpy array with the torch methods the public modules call."""

    def float(self):
        return self.astype(np.float32)

    def long(self):
        return self.astype(np.int64)

    def int(self):
        return self.astype(np.int32)

    def to(self, dtype):
        return self.astype(dtype)

    def unsqueeze(self, dim):
        return np.expand_dims(np.asarray(self), dim).view(Tensor)

    def squeeze(self, *dims):
        a = np.asarray(self)
        return (a.squeeze(*dims) if dims else a.squeeze()).view(Tensor)

    def numpy(self):
        return np.asarray(self)

    def item(self):
        return np.asarray(self).item()


def from_numpy(a: np.ndarray) -> Tensor:
    return np.asarray(a).view(Tensor)


def logical_and(a, b) -> Tensor:
    return np.logical_and(a, b).view(Tensor)


def logical_or(a, b) -> Tensor:
    return np.logical_or(a, b).view(Tensor)


def zeros_like(a) -> Tensor:
    return np.zeros_like(np.asarray(a)).view(Tensor)
