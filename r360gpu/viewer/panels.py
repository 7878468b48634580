"""imgui panels of the viewer (wgpu-py's imgui renderer, imgui-bundle, implot).

Two docked windows beside the pictures (never over them: the pictures are
laid out in what the docks leave, :mod:`r360gpu.viewer.docking`):

* "r360gpu viewer" (left edge): scenes A / B, comparison mode, camera,
  overlays with colour map / range / opacity and a colour bar, captures, status;
* "Metrics" (right edge or bottom, whichever leaves the larger pictures):
  per-view axes of the shown methods from results.json at evaluation views,
  the scene-level axes and RQS, the live geometric axis at any viewpoint,
  and an implot chart of the per-view axes along the evaluation camera path
  with the current view marked (click to jump); the key bindings instead
  while they are toggled on (H / F1).

On the panes themselves, also with the panels hidden (I): an "A: scene" /
"B: scene" label, and where a scene has no picture (a renders-only source
away from the evaluation cameras) the reason and what to press.

Widgets change the app through :meth:`ViewerApp.set_state` and
:meth:`ViewerApp.apply`, the same paths the keys take.
"""
from __future__ import annotations

import math

import numpy as np
from imgui_bundle import imgui, implot

from . import colormaps
from .results import AXES
from .state import COLORMAPS, COMPARE_MODES, KEY_BINDINGS, Action

PANEL_WIDTH = 330
METRICS_WIDTH = 380
#: Height of the Metrics dock when it runs along the bottom (logical px).
METRICS_HEIGHT = 270
#: Text lines kept at the bottom of the left panel for the status section.
STATUS_LINES = 5
LABEL_BG = (0.05, 0.05, 0.06, 0.75)
LABEL_FG = (1.0, 1.0, 1.0, 1.0)
MISSING_FG = (1.0, 0.85, 0.45, 1.0)
_AXIS_LABEL = {"s_sem": "s_sem", "s_geo": "s_geo", "s_str": "s_str"}
_COMPARE_LABEL = {"none": "single", "side": "side by side", "wipe": "A/B wipe"}


def _fmt(x, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{digits}f}"


class Panels:
    """The imgui layer of a :class:`r360gpu.viewer.app.ViewerApp`."""

    def __init__(self, app):
        from wgpu.utils.imgui import ImguiRenderer

        self.app = app
        self.renderer = ImguiRenderer(app.ctx.device, app.canvas, render_target_format=app.format)
        self.plot_context = implot.create_context()
        self.renderer.set_gui(self.draw)

    @staticmethod
    def dock_sizes() -> tuple[float, float, float]:
        """(left panel width, Metrics width when docked right, Metrics height when docked at the
        bottom), logical pixels."""
        return float(PANEL_WIDTH), float(METRICS_WIDTH), float(METRICS_HEIGHT)

    def render(self) -> None:
        """Draw the panels over the current canvas texture."""
        self.renderer.render()

    # -- windows --------------------------------------------------------------
    def draw(self) -> None:
        app = self.app
        self.pane_labels()
        if not app.state.show_ui:
            return
        docks = app.loop.docks
        self.main_window(docks.controls if docks is not None else None)
        rect = docks.metrics if docks is not None else None
        if rect is not None:
            self._dock_window(rect)
            imgui.begin("Keys (H)" if app.state.show_help else "Metrics", None, _docked_flags())
            if app.state.show_help:
                self.help_contents()
            else:
                self.metrics_contents(docks.metrics_side, rect)
            imgui.end()

    def _ratio(self) -> float:
        return float(self.app.canvas.get_pixel_ratio() or 1.0)

    def _dock_window(self, rect) -> None:
        """Place the next window exactly on a dock rectangle (framebuffer px)."""
        r = self._ratio()
        x, y, w, h = rect
        imgui.set_next_window_pos((x / r, y / r), imgui.Cond_.always)
        imgui.set_next_window_size((w / r, h / r), imgui.Cond_.always)

    def main_window(self, rect=None) -> None:
        app = self.app
        if rect is None:
            _, fb_h = app.framebuffer_size()
            rect = (0, 0, int(PANEL_WIDTH * self._ratio()), fb_h)
        self._dock_window(rect)
        imgui.begin("r360gpu viewer", None, _docked_flags())
        imgui.text(f"{app.bundle.name}  (prompt: {app.bundle.prompt})")
        # The controls scroll in a child region that leaves room for the status lines, so the
        # status (adapter, render size, messages such as where a capture went) stays in sight
        # in a short window (1280x720) instead of below the panel's fold.
        imgui.begin_child("controls", (0.0, -STATUS_LINES * imgui.get_text_line_height_with_spacing()))
        self.scenes_section()
        self.camera_section()
        self.overlay_section()
        self.capture_section()
        if app.loop.docks is not None and app.loop.docks.metrics is None:
            # No room for the Metrics dock: its contents here, below the controls.
            if imgui.collapsing_header("Keys" if app.state.show_help else "Metrics",
                                       imgui.TreeNodeFlags_.default_open):
                if app.state.show_help:
                    self.help_contents()
                else:
                    self.metrics_contents("left", None)
        imgui.end_child()
        self.status_section()
        imgui.end()

    # -- on the panes ------------------------------------------------------------
    def pane_labels(self) -> None:
        """"A: scene" / "B: scene" on the panes, and the reason where a scene has no picture."""
        app = self.app
        lay = app.last_layout
        if lay is None:
            return
        r = self._ratio()
        dl = imgui.get_background_draw_list(imgui.get_main_viewport())
        shown = app.state.shown()
        missing = set(app.pictures.missing)
        for i, name in enumerate(shown):
            x, y, w, h = (v / r for v in lay.rects[min(i, len(lay.rects) - 1)])
            if lay.mode == "wipe":  # one rectangle: A on the left of the line, B on the right
                wx = lay.wipe_x / r
                x, w = (x, wx - x) if i == 0 else (wx, x + w - wx)
            label = f"{'AB'[i]}: {name}"
            size = imgui.calc_text_size(label)
            lx = x + 6 if i == 0 or lay.mode != "wipe" else x + w - size.x - 14
            _boxed_text(dl, (lx, y + 6), label, LABEL_FG)
            if name in missing:
                text = app.pictures.missing_reason(name)
                wrap = max(80.0, w - 24)
                tsize = imgui.calc_text_size(text, False, wrap)
                _boxed_text(dl, (x + (w - tsize.x) / 2, y + (h - tsize.y) / 2), text, MISSING_FG, wrap=wrap)

    def scenes_section(self) -> None:
        app, s = self.app, self.app.state
        if not imgui.collapsing_header("Scenes", imgui.TreeNodeFlags_.default_open):
            return
        imgui.text("A  B")
        for i, name in enumerate(s.scenes):
            if imgui.radio_button(f"##a{i}", s.scene_a == i):
                app.set_state(app.state.with_scene("a", i))
            imgui.same_line()
            if imgui.radio_button(f"##b{i}", s.scene_b == i):
                app.set_state(app.state.with_scene("b", i))
            imgui.same_line()
            imgui.text(f"{i + 1}  {name}  [{app.layers[name].kind}]")
        changed, k = imgui.combo("compare", COMPARE_MODES.index(s.compare), [_COMPARE_LABEL[m] for m in COMPARE_MODES])
        if changed:
            app.set_state(_replace(app.state, compare=COMPARE_MODES[k]))
        if s.compare == "wipe":
            changed, w = imgui.slider_float("wipe", s.wipe, 0.0, 1.0)
            if changed:
                app.set_state(app.state.with_wipe(w))
        if imgui.button("swap A/B (T)"):
            app.key("t")

    def camera_section(self) -> None:
        app, s, cam = self.app, self.app.state, self.app.camera
        if not imgui.collapsing_header("Camera", imgui.TreeNodeFlags_.default_open):
            return
        if imgui.radio_button("orbit", s.camera_mode == "orbit"):
            app.set_state(_replace(app.state, camera_mode="orbit"))
        imgui.same_line()
        if imgui.radio_button("fly (G)", s.camera_mode == "fly"):
            app.set_state(_replace(app.state, camera_mode="fly"))
        changed, fov = imgui.slider_float("fov (deg)", float(cam.fov_y), 5.0, 150.0, "%.1f")
        if changed:
            cam.set_fov(fov)
            app.request_draw()
        for label, action in (("reset (R)", "reset"), ("focus target (F)", "focus"), ("level (L)", "level")):
            if imgui.button(label):
                app.apply(Action(action))
                app.set_state(app.state.moved())
            imgui.same_line()
        imgui.new_line()
        if imgui.button(f"up axis: {cam.up_choice} (U)"):
            app.apply(Action("up"))
        if app.views:
            if imgui.button("< prev"):
                app.key("ArrowLeft")
            imgui.same_line()
            if imgui.button("next >"):
                app.key("ArrowRight")
            imgui.same_line()
            if imgui.button("snap (Space)"):
                app.apply(Action("snap"))
            view = app.current_view()
            if view is not None:
                imgui.text(f"view {s.view_index + 1}/{len(app.views)}: {view}")
            else:
                imgui.text_colored((0.8, 0.8, 0.5, 1.0), "free camera (not an evaluation view)")

    def overlay_section(self) -> None:
        app, ov = self.app, self.app.state.overlays
        if not imgui.collapsing_header("Overlays", imgui.TreeNodeFlags_.default_open):
            return
        for attr, label in (("depth", "depth (Z)"), ("delta_heat", "|dD| heat map (X)"), ("changed", "changed mask (V)"),
                            ("outline", "target outline (B)"), ("probes", "probe masks (N)"),
                            ("residuals", "residual highlight (O)")):
            changed, v = imgui.checkbox(label, getattr(ov, attr))
            if changed:
                app.set_state(app.state.with_overlays(**{attr: v}))
        changed, k = imgui.combo("colour map (M)", COLORMAPS.index(ov.colormap), list(COLORMAPS))
        if changed:
            app.set_state(app.state.with_overlays(colormap=COLORMAPS[k]))
        self.colour_bar(ov.colormap)
        changed, a = imgui.slider_float("opacity ([ ])", ov.opacity, 0.0, 1.0)
        if changed:
            app.set_state(app.state.with_overlays(opacity=a))
        self.range_widget("depth", "depth_auto", "depth_range", ov)
        self.range_widget("|dD|", "delta_auto", "delta_range", ov)
        for name, st in app.last_delta.items():
            # GHT on this pane's own |dD| histogram: at the pane's resolution, so it can differ from
            # the evaluation's t_depth (Metrics panel / report), which is computed at the evaluation size.
            imgui.text(f"{name}: changed = |dD| > {st.threshold:.4g} (GHT at pane resolution)")
            imgui.text(f"    |dD| range {st.lo:.3g} .. {st.hi:.3g}")
        if ov.probes and app.probe_found:
            names = [f"{p.probe} ({p.kind}, {p.masks.shape[0]})" for p in app.probe_found]
            changed, k = imgui.combo("probe", min(app.pictures.probe_choice, len(names) - 1), names)
            if changed:
                app.pictures.probe_choice = k
                app.request_draw()
        elif ov.probes:
            imgui.text_disabled("no cached probe masks for this view")

    def range_widget(self, label: str, auto_attr: str, range_attr: str, ov) -> None:
        app = self.app
        changed, auto = imgui.checkbox(f"auto {label} range", getattr(ov, auto_attr))
        if changed:
            app.set_state(app.state.with_overlays(**{auto_attr: auto}))
        if not getattr(ov, auto_attr):
            lo, hi = getattr(ov, range_attr)
            changed, lo, hi = imgui.drag_float_range2(f"{label} range", float(lo), float(hi), 0.01, 0.0, 0.0, "%.3f")
            if changed and hi > lo:
                app.set_state(app.state.with_overlays(**{range_attr: (lo, hi)}))

    def colour_bar(self, name: str) -> None:
        """The colour map as a horizontal strip of 64 cells."""
        lut = colormaps.lut(name)
        dl = imgui.get_window_draw_list()
        pos = imgui.get_cursor_screen_pos()
        x0, y0 = pos.x, pos.y
        width = imgui.get_content_region_avail().x
        n = 64
        cw = width / n
        for k in range(n):
            r, g, b, _ = lut[int(round(k * (len(lut) - 1) / (n - 1)))]
            col = imgui.get_color_u32((float(r), float(g), float(b), 1.0))
            dl.add_rect_filled((x0 + k * cw, y0), (x0 + (k + 1) * cw + 1, y0 + 10), col)
        imgui.dummy((width, 12))

    def capture_section(self) -> None:
        app = self.app
        if not imgui.collapsing_header("Capture"):
            return
        if imgui.button("screenshot view (P)"):
            app.apply(Action("screenshot", "view"))
        imgui.same_line()
        if imgui.button("with panels (Shift+P)"):
            app.apply(Action("screenshot", "window"))
        label = "stop recording (K)" if app.recorder is not None else "record camera path (K)"
        if imgui.button(label):
            app.key("k")
        if app.recorder is None and imgui.button("record a fly-through of the evaluation path"):
            app.fly_evaluation_path()
        if app.recorder is not None:
            imgui.text(f"{len(app.recorder.cameras)} frames -> {app.recorder.folder}")
        imgui.text_wrapped(f"saved to {app.capture_dir}")

    def status_section(self) -> None:
        app = self.app
        imgui.separator()
        info = app.ctx.adapter_info
        imgui.text_wrapped(f"{info.get('name')} [{info.get('backend')}]")
        cam = app.last_camera
        if cam is not None:
            imgui.text(f"render {cam.width}x{cam.height} (scale {app.last_scale:.2f}), "
                       f"{1000 * app.frame_seconds:.0f} ms/frame")
        now = app.clock()
        for t, text in app.messages:
            if now - t < 4.0:
                imgui.text_wrapped(text)

    # -- metrics --------------------------------------------------------------
    def metrics_contents(self, side: str, rect) -> None:
        """The Metrics dock: text, and the per-view chart beside it (bottom dock) or below it."""
        app = self.app
        charted = [n for n in dict.fromkeys(app.state.shown())
                   if n != "pre" and app.results is not None and n in app.results.methods]
        chart = bool(charted and app.views)
        if side == "bottom" and chart:
            r = self._ratio()
            width = rect[2] / r
            if imgui.begin_table("metrics-dock", 2, imgui.TableFlags_.sizing_stretch_prop):
                imgui.table_setup_column("numbers", imgui.TableColumnFlags_.width_fixed, min(420.0, width * 0.45))
                imgui.table_setup_column("chart", imgui.TableColumnFlags_.width_stretch)
                imgui.table_next_row()
                imgui.table_next_column()
                self.metrics_text()
                imgui.table_next_column()
                self.chart(charted[0], (imgui.get_content_region_avail().x, rect[3] / r - 40))
                imgui.end_table()
            return
        self.metrics_text()
        if chart:
            self.chart(charted[0], (imgui.get_content_region_avail().x, 230))

    def metrics_text(self) -> None:
        app = self.app
        methods = [n for n in dict.fromkeys(app.state.shown()) if n != "pre"]
        view = app.current_view()
        res = app.results
        if res is None:
            imgui.text_disabled("no results file (start with --results results.json)")
        for name in methods:
            imgui.separator()
            imgui.text(name)
            m = res.methods.get(name) if res is not None else None
            if m is not None:
                ax = m.axes
                imgui.text(f"scene:  s_sem {_fmt(ax.get('s_sem'))}  s_geo {_fmt(ax.get('s_geo'))}  "
                           f"s_str {_fmt(ax.get('s_str'))}")
                imgui.text(f"        RQS {_fmt(ax.get('rqs'))}")
                va = m.views.get(view) if view is not None else None
                if va is not None:
                    imgui.text(f"view:   s_sem {_fmt(va.s_sem, 0)}  s_geo {_fmt(va.s_geo)}  s_str {_fmt(va.s_str)}")
                    imgui.text(f"        IoU_post {_fmt(va.iou_post)}  IoU_drop {_fmt(va.iou_drop)}")
                elif view is None:
                    imgui.text_disabled("per-view axes at evaluation views only")
            elif res is not None and name != "reference":
                imgui.text_disabled("not in the results file")
            live = app.live.get(name)
            if live is not None:
                stale = "  (moving...)" if app.live_stale else ""
                imgui.text(f"live:   s_geo {_fmt(live.acc_depth)}  t_depth (GHT, {live.width}x{live.height}) "
                           f"{live.threshold:.4g}{stale}")
                imgui.text(f"        {live.n_changed_in_mask}/{live.n_mask} target px changed")
                imgui.text(f"        {live.mask_kind} mask, {live.width}x{live.height}")
        if app.live_note:
            imgui.text_disabled(app.live_note)
        elif not app.live and methods:
            imgui.text_disabled("live axis: measured when the camera rests")

    def chart(self, method: str, size=(METRICS_WIDTH - 16, 230)) -> None:
        """Per-view axes of ``method`` along the evaluation path; the current view marked; click to jump."""
        app = self.app
        x = np.arange(len(app.views), dtype=np.float64)
        m = app.results.methods[method]
        if implot.begin_plot(f"per-view axes: {method}", (max(120.0, size[0]), max(120.0, size[1]))):
            implot.setup_axes("evaluation view", "score")
            implot.setup_axis_limits(implot.ImAxis_.y1, -0.05, 1.05, implot.Cond_.always)
            implot.setup_axis_limits(implot.ImAxis_.x1, -0.5, len(app.views) - 0.5, implot.Cond_.once)
            implot.setup_legend(implot.Location_.south, implot.LegendFlags_.outside | implot.LegendFlags_.horizontal)
            for axis in AXES:
                y = np.asarray(m.series(axis, app.views), np.float64)
                spec = implot.Spec()
                spec.marker = implot.Marker_.circle
                spec.marker_size = 3
                implot.plot_line(_AXIS_LABEL[axis], x, y, spec)
            s = app.state
            if s.view_index is not None:
                implot.plot_inf_lines("current view", np.array([float(s.view_index)]))
            if implot.is_plot_hovered() and imgui.is_mouse_clicked(imgui.MouseButton_.left):
                px = implot.get_plot_mouse_pos().x
                idx = int(min(len(app.views) - 1, max(0, round(px))))
                app.jump_to_view(idx)
                app.request_draw()
            implot.end_plot()

    def help_contents(self) -> None:
        if imgui.begin_table("keys", 2, imgui.TableFlags_.row_bg | imgui.TableFlags_.borders_inner_v):
            imgui.table_setup_column("keys", imgui.TableColumnFlags_.width_fixed,
                                     max(imgui.calc_text_size(k).x for k, _ in KEY_BINDINGS) + 8)
            imgui.table_setup_column("action", imgui.TableColumnFlags_.width_stretch)
            for keys, what in KEY_BINDINGS:
                imgui.table_next_row()
                imgui.table_next_column()
                imgui.text(keys)
                imgui.table_next_column()
                imgui.text_wrapped(what)
            imgui.end_table()


def _docked_flags():
    f = imgui.WindowFlags_
    return f.no_move | f.no_resize | f.no_collapse


def _boxed_text(dl, pos, text: str, rgba, *, wrap: float = 0.0) -> None:
    """``text`` at ``pos`` (logical px) on a dark box, on draw list ``dl``."""
    size = imgui.calc_text_size(text, False, wrap if wrap else -1.0)
    x, y = pos
    dl.add_rect_filled((x - 5, y - 3), (x + size.x + 5, y + size.y + 3), imgui.get_color_u32(LABEL_BG), 4.0)
    if wrap:
        dl.add_text(imgui.get_font(), imgui.get_font_size(), (x, y), imgui.get_color_u32(rgba), text, wrap)
    else:
        dl.add_text((x, y), imgui.get_color_u32(rgba), text)


def _replace(state, **changes):
    from dataclasses import replace

    return replace(state, **changes)
