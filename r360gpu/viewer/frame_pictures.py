"""The pictures of one frame: each shown scene rendered (or read from its renders) and overlaid.

:class:`Pictures` decides which layers a frame reads (the shown scenes, plus
pre for the |dD| overlays), the picture aspect and render size, renders
every shown scene at the frame's camera (:mod:`r360gpu.viewer.layers`; unchanged
cameras are not re-rendered) and records the overlay pass of each
(:mod:`r360gpu.viewer.overlays`) into a device buffer the compositor draws.  It
keeps the device copies of target masks and probe masks at render size.
"""
from __future__ import annotations

import numpy as np

from r360gpu.io.masks import load_mask

from .compose import Layout
from .layers import PlaneImage, camera_key
from .live import delta_stats
from ..util.resize import resize_nearest
from .overlays import OverlaySettings

#: Target masks kept in memory (read from disk again after that).
MASK_CACHE = 32


class Pictures:
    """Rendering and overlays of one :class:`r360gpu.viewer.app.ViewerApp`.

    After :meth:`render`: ``last_delta`` {scene: DeltaStats} of the |dD|
    overlays, ``missing`` the shown scenes without a picture here (a
    renders-only source away from its evaluation cameras), ``probe_found``
    the cached probe masks of the view; ``probe_choice`` picks one of them.
    """

    def __init__(self, app):
        self.app = app
        self.last_delta: dict = {}
        self.missing: list[str] = []
        self.probe_found: list = []
        self.probe_choice = 0
        self._buffers: list = [None, None]
        self._masks: dict = {}
        self._mask_buffers: dict = {}
        self._probe_buffers: dict = {}
        self._frame_cache: dict = {}

    # -- what to render ---------------------------------------------------------
    def involved(self) -> list[str]:
        """Layers this frame reads: the shown scenes, plus pre for the |dD| overlays."""
        s = self.app.state
        names = list(dict.fromkeys(s.shown()))
        if s.overlays.any_delta() and "pre" not in names:
            names.append("pre")
        return names

    def aspect(self, view: str | None) -> float | None:
        """Width / height the pictures must keep: the evaluation camera's or renders' on a view."""
        app = self.app
        a = app.camera.aspect()
        if a is not None:
            return a
        if view is not None:
            for name in app.state.shown():
                layer = app.layers[name]
                if layer.kind == "renders" and layer.available(view):
                    w, h = layer.native_size(view)
                    return w / h
        return None

    def render_size(self, lay: Layout, scale: float, view: str | None) -> tuple[int, int]:
        """Per-picture render size: the layout's at ``scale``; on a view with a renders source
        involved, that source's own size (so every picture and |dD| share one size)."""
        if view is not None:
            for name in self.involved():
                layer = self.app.layers[name]
                if layer.kind == "renders" and layer.available(view):
                    return layer.native_size(view)
        return lay.render_size(scale)

    # -- rendering ------------------------------------------------------------------
    def render(self, cam, view: str | None, lay: Layout) -> list:
        """Render and overlay every shown scene; returns [(buffer, width, height) or None] per picture."""
        app = self.app
        s, ov = app.state, app.state.overlays
        ckey = camera_key(cam)
        if self._frame_cache.get("key") != (ckey, view):
            self._frame_cache = {"key": (ckey, view)}
        fc = self._frame_cache
        for name in self.involved():
            app.layers[name].load()  # loading a scene file is not rendering time
        t0 = app.clock()
        rendered = 0
        images: dict[str, PlaneImage | None] = {}
        for name in self.involved():
            layer = app.layers[name]
            if ov.residuals and name in s.shown():  # key O: the Gaussians coloured by their residual
                layer = app.residuals.layer(name) or layer
                layer.load()
            before = layer.renders_done
            images[name] = layer.image(cam, view)
            rendered += layer.renders_done - before
        if rendered:
            app.policy.observe(rendered * cam.width * cam.height, app.clock() - t0)
        pictures = []
        enc = app.ctx.encoder()
        self.last_delta = {}
        self.missing = []
        for i, name in enumerate(s.shown()):
            img = images.get(name)
            if img is None:
                pictures.append(None)
                self.missing.append(name)
                continue
            settings = OverlaySettings(
                depth=ov.depth, delta_heat=ov.delta_heat, changed=ov.changed, outline=ov.outline and view is not None,
                probes=ov.probes and view is not None, colormap=ov.colormap, opacity=ov.opacity,
                depth_range=ov.depth_range, heat_range=ov.delta_range,
                outline_px=max(1, int(round(1.5 * img.width / max(1, lay.rects[0][2])))),
            )
            if ov.depth and ov.depth_auto:
                rng = fc.get(("depth", name))
                if rng is None:
                    rng = fc[("depth", name)] = app.overlay.depth_range(img) or (0.0, 1.0)
                settings.depth_range = rng
            pre = images.get("pre") if ov.any_delta() and name != "pre" else None
            if not (app.layers["pre"].has_depth and app.layers[name].has_depth):
                pre = None  # renders without depth: no |dD|
            if pre is not None and pre.size == img.size:
                st = fc.get(("delta", name))
                if st is None:
                    st = fc[("delta", name)] = delta_stats(app.ctx, pre, img)
                settings.delta = st
                self.last_delta[name] = st
                if ov.delta_auto:
                    settings.heat_range = (0.0, st.hi if st.hi > 0 else 1.0)
            else:
                pre = None
            mask = self.mask_buffer(view, img.width, img.height) if settings.outline else None
            ids = self.probe_buffer(name, view, img.width, img.height) if settings.probes else None
            out = self._buffers[i] = app.overlay.output_buffer(img.width, img.height, self._buffers[i])
            app.overlay.record(enc, img, settings, out, pre=pre, mask=mask, probe_ids=ids)
            pictures.append((out, img.width, img.height))
        app.ctx.submit(enc)
        return pictures

    def missing_reason(self, name: str) -> str:
        """Why scene ``name`` has no picture at this viewpoint (one line for the pane)."""
        layer = self.app.layers[name]
        if layer.kind == "renders":
            return (f"{name}: renders exist at the evaluation cameras only: press Space "
                    "(or Left / Right) to go to one")
        return f"{name}: nothing to show here"

    # -- masks --------------------------------------------------------------------------
    def mask_of(self, view: str, width: int, height: int) -> np.ndarray:
        """The view's target mask (bool) at ``width x height`` (nearest-neighbour)."""
        m = self._masks.get(view)
        if m is None:
            while len(self._masks) >= MASK_CACHE:
                self._masks.pop(next(iter(self._masks)))
            m = self._masks[view] = load_mask(self.app.bundle.masks[view])
        return resize_nearest(m, (height, width), axes=(0, 1))

    def mask_buffer(self, view: str | None, width: int, height: int):
        if view is None or view not in self.app.bundle.masks:
            return None
        key = (view, width, height)
        buf = self._mask_buffers.get(key)
        if buf is None:
            if len(self._mask_buffers) > 8:
                self._mask_buffers.clear()
            buf = self._mask_buffers[key] = self.app.overlay.upload_mask(self.mask_of(view, width, height))
        return buf

    def probe_buffer(self, name: str, view: str | None, width: int, height: int):
        """Probe instance ids of the chosen cached probe for (scene, view) at the render size, or None."""
        from .probe_masks import cached_masks, instance_ids

        app = self.app
        if view is None or app.results is None:
            return None
        key = (name, view)
        entry = self._probe_buffers.get(key)
        if entry is None:
            if len(self._probe_buffers) >= 16:
                self._probe_buffers.clear()
            layer = app.layers[name]
            idx = app.views.index(view)
            try:
                rgb = layer.host_rgb(view, app.view_cameras[idx])
                found = cached_masks(app.results.probe_cache, app.results.probes, rgb,
                                     app.results.prompt or app.bundle.prompt)
            except Exception as e:  # noqa: BLE001 - a broken cache must not take the viewer down
                app.notify(f"probe cache: {e}")
                found = []
            entry = self._probe_buffers[key] = {"found": found, "buffers": {}}
        self.probe_found = entry["found"]
        if not entry["found"]:
            return None
        pm = entry["found"][min(self.probe_choice, len(entry["found"]) - 1)]
        bkey = (pm.probe, width, height)
        buf = entry["buffers"].get(bkey)
        if buf is None:
            ids = instance_ids(pm.masks)
            buf = entry["buffers"][bkey] = app.overlay.upload_ids(resize_nearest(ids, (height, width), axes=(0, 1)))
        return buf
