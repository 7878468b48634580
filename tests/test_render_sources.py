"""The scene sources share one declared interface (render.sources.Source): the three sources are
sources, a caller's own complete source is taken and bound, a partial one is refused by name."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.io.gaussians import random_gaussians
from r360gpu.render.sources import DeviceViewsSource, RendersSource, SceneSource, Source, ViewImages, open_source


def test_every_source_is_a_source(ctx):
    scene = SceneSource(random_gaussians(20, sh_degree=0, seed=1), ctx=ctx)
    renders = object.__new__(RendersSource)  # the members are the class's; no folder needed to check them
    device = DeviceViewsSource({}, ctx=ctx)
    for src, kind in ((scene, "scene"), (renders, "renders"), (device, "device")):
        assert isinstance(src, Source), type(src).__name__
        assert src.kind == kind
    assert open_source(scene, ctx=ctx) is scene
    scene.release()


class OwnSource:
    kind = "device"

    def __init__(self):
        self.bound = "never"

    def images(self, view, camera=None):
        return ViewImages(np.zeros((2, 3, 3), np.float32), None)

    def describe(self):
        return {"kind": self.kind, "name": "own"}

    def bind(self, ctx):
        self.bound = ctx

    def release(self):
        pass


def test_a_callers_own_source_is_taken_and_bound(ctx):
    own = OwnSource()
    assert open_source(own, ctx=ctx) is own
    assert own.bound is ctx


def test_a_partial_source_is_refused_naming_what_it_lacks():
    class Partial:
        def images(self, view, camera=None):
            raise AssertionError("not called")

        def describe(self):
            return {}

    with pytest.raises(InputError, match=r"Partial is not a source \(r360gpu\.render\.sources\.Source\): "
                                         r"it has no kind, bind, release"):
        open_source(Partial())
