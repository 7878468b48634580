"""What the report's first screen says, computed from a results document (no HTML here).

* :func:`probe_verdicts` -- per scene, the validity of each axis' probe
  (``scenes.S.validity.{s_sem,s_geo,s_str}``: "ok" / "weak" / "blind") with
  one sentence per verdict that is not "ok", citing the control scores
  (``scenes.S.controls.{identity,reference}.axes``) when present;
* :func:`doubtful_axes` -- axes whose probe is not "ok" in some scene (the
  Overall table marks them);
* :func:`view_rows` -- every (scene, method, view) with its per-view axes;
* :func:`worst_views` -- per method, the view that leaks most (none when no view leaks);
* :func:`expectation_checks` -- for bundles that state their methods' known
  failures (``scenes.S.expected``, from scene.toml ``[expected.METHOD]``):
  which axis should catch each failure and whether it did.

Missing sections give empty answers: a results document without validity,
controls or expectations renders as before.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..protocol import AXES, XI_DEFAULT
from .results_io import method_entry, method_names, number, scene_names

VERDICTS = ("ok", "weak", "blind")
#: An axis below this value counts as low: a warning banner, and a failure "caught".
LOW_AXIS = 0.5

_WHAT = {"s_sem": "the semantic probe", "s_geo": "the depth change (GHT threshold)",
         "s_str": "the structural probe"}


def _controls_text(controls: dict, axis: str) -> str:
    vals = []
    for name, meaning in (("identity", "nothing removed"), ("reference", "the true removal")):
        v = number(((controls.get(name) or {}).get("axes") or {}).get(axis))
        if v is not None:
            vals.append(f"{v:.3f} on the {name} control ({meaning})")
    return f" It scores {' and '.join(vals)}." if vals else ""


def verdict_sentence(axis: str, verdict: str, controls: dict | None = None) -> str:
    """One sentence explaining a verdict that is not "ok" (controls: the scene's control scores)."""
    what = _WHAT.get(axis, axis)
    if verdict == "blind":
        text = (f"{axis} is blind here: {what} scores the unchanged scene about like the true removal, "
                "so its values say nothing about the methods in this scene.")
    elif verdict == "weak":
        text = (f"{axis} is weak here: {what} separates the unchanged scene from the true removal only "
                "partly, so small differences between methods on this axis are not meaningful.")
    else:
        text = f"{axis}: unknown verdict {verdict!r}."
    return text + _controls_text(controls or {}, axis)


@dataclass(frozen=True)
class Verdict:
    scene: str
    axis: str
    verdict: str  # "ok", "weak", "blind", or "" when not given
    sentence: str  # empty for "ok"


def probe_verdicts(results: dict) -> list[Verdict]:
    """Per scene with a ``validity`` section, one :class:`Verdict` per axis."""
    out = []
    for s in scene_names(results):
        sd = (results.get("scenes") or {}).get(s) or {}
        validity = sd.get("validity")
        if not isinstance(validity, dict):
            continue
        controls = sd.get("controls") if isinstance(sd.get("controls"), dict) else {}
        for axis in AXES:
            v = validity.get(axis)
            v = str(v) if v is not None else ""
            sentence = "" if v in ("ok", "") else verdict_sentence(axis, v, controls)
            out.append(Verdict(s, axis, v, sentence))
    return out


def doubtful_axes(results: dict) -> dict[str, list[str]]:
    """{axis: [scenes where its probe is not "ok"]} (only axes with such a scene)."""
    out: dict[str, list[str]] = {}
    for v in probe_verdicts(results):
        if v.verdict not in ("ok", ""):
            out.setdefault(v.axis, []).append(v.scene)
    return out


def controls(results: dict) -> list[tuple[str, str, dict]]:
    """(scene, control name, axes) of every control present."""
    out = []
    for s in scene_names(results):
        c = ((results.get("scenes") or {}).get(s) or {}).get("controls")
        if isinstance(c, dict):
            for name in ("identity", "reference"):
                if isinstance(c.get(name), dict):
                    out.append((s, name, c[name].get("axes") or {}))
    return out


# -- per view ----------------------------------------------------------------------

def _view_axes(rec: dict, xi: float = XI_DEFAULT) -> dict:
    """Per-view values of one view record: iou_pre, iou_post (most alarming probe), s_sem (1 when no
    probe finds the object at ``xi``), acc_depth, t_depth, no_depth (pixels of M with no depth after
    removal: a see-through hole), sim_sam, s_str, psnr, ssim, lpips."""
    out: dict = {"view": str(rec.get("view"))}
    sems = [v for v in (rec.get("semantic") or {}).values() if isinstance(v, dict)]
    scored = [v for v in sems if not v.get("empty_target")]
    if scored:
        worst = max(scored, key=lambda v: number(v.get("iou_post")) or 0.0)
        out["iou_pre"], out["iou_post"] = number(worst.get("iou_pre")), number(worst.get("iou_post"))
        out["s_sem"] = 0.0 if (out["iou_post"] or 0.0) >= xi else 1.0
    geo = rec.get("geometric") or {}
    if geo and not geo.get("excluded"):
        out["acc_depth"] = number(geo.get("acc_depth"))
        out["t_depth"] = number(geo.get("threshold"))
        out["no_depth"] = number(geo.get("n_no_depth_in_mask"))  # None in results written before the count
    strs = [v for v in (rec.get("structural") or {}).values() if isinstance(v, dict) and not v.get("empty_target")]
    if strs:
        worst = min(strs, key=lambda v: number(v.get("s_str")) if number(v.get("s_str")) is not None else 1.0)
        out["sim_sam"], out["s_str"] = number(worst.get("sim_sam")), number(worst.get("s_str"))
    fid = rec.get("fidelity") or {}
    for k in ("psnr", "ssim", "lpips"):
        if number(fid.get(k)) is not None:
            out[k] = number(fid.get(k))
    out["excluded"] = bool(sems) and not scored
    return out


def leak_score(row: dict) -> float | None:
    """Mean of the view's removal axes (s_sem 0/1, acc_depth, s_str): lower leaks more; None when none."""
    vals = [row[k] for k in ("s_sem", "acc_depth", "s_str") if row.get(k) is not None and math.isfinite(row[k])]
    return sum(vals) / len(vals) if vals else None


def view_rows(results: dict) -> list[dict]:
    """One dict per (scene, method, view) in display order: the keys of the per-view values plus
    scene, method, picture (relative path or None) and leak (:func:`leak_score`)."""
    out = []
    for s in scene_names(results):
        for m in method_names(results):
            entry = method_entry(results, s, m)
            if entry is None:
                continue
            pics = entry.get("pictures") or {}
            for rec in entry.get("views") or []:
                row = _view_axes(rec)
                row.update(scene=s, method=m, picture=pics.get(row["view"]), leak=leak_score(row))
                out.append(row)
    return out


def leaks(row: dict, low: float = LOW_AXIS) -> bool:
    """Whether the view leaks: one of its removal axes (s_sem 0/1, acc_depth, s_str) is below ``low``,
    the threshold at which the known-failure check counts a failure as caught."""
    return any(row.get(k) is not None and math.isfinite(row[k]) and row[k] < low
               for k in ("s_sem", "acc_depth", "s_str"))


def worst_views(results: dict, rows: list[dict] | None = None) -> dict[str, dict]:
    """Per method, the view row with the lowest :func:`leak_score` among the views that
    :func:`leaks` (first in display order on ties); a method none of whose views leaks has none."""
    out: dict[str, dict] = {}
    for row in rows if rows is not None else view_rows(results):
        if row["leak"] is None or not leaks(row):
            continue
        best = out.get(row["method"])
        if best is None or row["leak"] < best["leak"]:
            out[row["method"]] = row
    return out


# -- expected failures -------------------------------------------------------------

@dataclass(frozen=True)
class Expectation:
    """One method's known failure in one scene and what the axes made of it.

    checks: (axis, value, caught) per axis in ``caught_by`` (caught: value < LOW_AXIS);
    for a method without a failure (``caught_by`` empty): ("lowest axis", value, value < LOW_AXIS),
    where "caught" means a false alarm.
    """

    scene: str
    method: str
    failure: str
    caught_by: tuple[str, ...]
    checks: tuple[tuple[str, float | None, bool | None], ...]

    @property
    def outcome(self) -> str:
        """"caught" (every expected axis low), "partly", "missed", "passes", "false alarm" or "no data"."""
        got = [c for _, _, c in self.checks if c is not None]
        if not got:
            return "no data"
        if not self.caught_by:
            return "false alarm" if got[0] else "passes"
        if all(got):
            return "caught" if len(got) == len(self.caught_by) else "partly"
        return "partly" if any(got) else "missed"


def expectation_checks(results: dict, low: float = LOW_AXIS) -> list[Expectation]:
    """Every (scene, method) with an ``expected`` entry, checked against the method's scene axes."""
    out = []
    for s in scene_names(results):
        expected = ((results.get("scenes") or {}).get(s) or {}).get("expected")
        if not isinstance(expected, dict):
            continue
        for m in method_names(results):
            e = expected.get(m)
            entry = method_entry(results, s, m)
            if not isinstance(e, dict) or entry is None:
                continue
            axes = entry.get("axes") or {}
            caught_by = tuple(a for a in AXES if a in (e.get("caught_by") or []))
            if caught_by:
                checks = []
                for a in caught_by:
                    v = number(axes.get(a))
                    checks.append((a, v, None if v is None else v < low))
            else:
                vals = [(a, number(axes.get(a))) for a in AXES if number(axes.get(a)) is not None]
                a, v = min(vals, key=lambda t: t[1]) if vals else ("lowest axis", None)
                checks = [(a, v, None if v is None else v < low)]
            out.append(Expectation(s, m, str(e.get("failure", "")), caught_by, tuple(checks)))
    return out
