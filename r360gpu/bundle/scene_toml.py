"""scene.toml: read it and check its keys, types and values into a :class:`~.model.Draft`.

Every problem is reported through ``bad`` (the file, and what is wrong) and parsing goes on, so one
``r360gpu check`` lists all there is to fix: TOML syntax, required keys, unknown keys (with a
suggestion), types and values, and the scene name.  Files and folders the keys name are checked
later, with every other layout's (:mod:`.load`).  The format is described in ``docs/scene-toml.md``.
"""
from __future__ import annotations

import difflib
import math
import re
from dataclasses import replace
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from .model import (DEPTH_MODES, PRINCIPAL_POINTS, RENDER_KEYS, BundleOptions, Draft, Problem, RenderSettings,
                    SourceSpec)
from .names import bad_name

CONFIG_NAME = "scene.toml"
TOP_KEYS = ("name", "prompt", "cameras", "masks", "views", "frame", "pre", "reference", "methods", "options",
            "expected", "target")
SOURCE_KEYS = ("scene", "renders", "rgb", "depth", "depth_scale", "frame", "orbit") + RENDER_KEYS
OPTION_KEYS = ("background", "depth", "reference_free")
_DUPLICATE_TABLE = re.compile(r"Cannot declare \('methods', '((?:[^'\\]|\\.)*)'\) twice(.*)")


def draft_from_config(root: Path, config: Path, problems: list[Problem], *, views: list[str] | None,
                      prompt: str | None) -> Draft | None:
    """The bundle ``config`` declares (None when it cannot be read as TOML); every problem found is
    appended to ``problems``.  views / prompt: given on the command line, they replace scene.toml's."""
    cfg = str(config)

    def bad(message: str) -> None:
        problems.append(Problem(cfg, message))

    data = _read_toml(config, bad)
    if data is None:
        return None
    d = Draft(root=root, layout="scene.toml", config=config)
    _unknown_keys(data, TOP_KEYS, None, bad)
    _parse_name(d, data, bad)
    _parse_prompt(d, data, prompt, bad, problems)
    _parse_locations(d, data, views, bad)
    _parse_sources(d, data, bad)
    if "options" in data:
        d.options = _parse_options(data["options"], bad)
    if "expected" in data:
        from .expected import parse_expected

        d.expected = parse_expected(data["expected"], list(d.methods), bad)
    return d


def _read_toml(config: Path, bad) -> dict | None:
    try:
        return tomllib.loads(config.read_text(encoding="utf-8-sig"))  # a BOM is accepted
    except OSError as e:
        bad(f"cannot read: {e.strerror or e}")
    except UnicodeDecodeError:
        bad("not UTF-8 text")
    except tomllib.TOMLDecodeError as e:
        m = _DUPLICATE_TABLE.match(str(e))
        if m:
            bad(f"duplicate method: [methods.{m.group(1)}] is declared twice{m.group(2)}")
        else:
            bad(f"invalid TOML: {e}")
    return None


def _parse_name(d: Draft, data: dict, bad) -> None:
    d.name = _default_name(d.root)
    if "name" in data:
        if isinstance(data["name"], str) and data["name"].strip():
            d.name = data["name"]
        else:
            bad("'name' must be a non-empty string")
    reason = bad_name(d.name)
    if reason:
        bad(f"scene name {d.name!r} {reason} (it names output folders); set name = \"...\"")


def _parse_prompt(d: Draft, data: dict, prompt: str | None, bad, problems: list[Problem]) -> None:
    if prompt is not None:
        if prompt.strip():
            d.prompt = prompt.strip()
        else:
            problems.append(Problem(None, "the prompt given is empty"))
    elif "prompt" not in data:
        bad("missing required key 'prompt': the category of the removed object, e.g. prompt = \"sofa\"")
    elif isinstance(data["prompt"], str) and data["prompt"].strip():
        d.prompt = data["prompt"].strip()
    else:
        bad("'prompt' must be a non-empty string")


def _parse_locations(d: Draft, data: dict, views: list[str] | None, bad) -> None:
    """Where the views come from: cameras, frame, [target], masks and the view selection."""
    root = d.root
    if "cameras" in data:
        if isinstance(data["cameras"], str) and data["cameras"].strip():
            d.cameras_path = root / data["cameras"]
        else:
            bad("'cameras' must be a path (a non-empty string)")
    if "frame" in data:
        d.frame = _frame_value(data["frame"], "", bad)
    if "target" in data:  # [target]: the object in 3D or by a few views' masks (bundle.target)
        from .target import parse_target_table

        d.target = parse_target_table(data["target"], root, bad)
    if "masks" not in data:
        if "target" not in data:
            bad("missing required key 'masks': the folder of target-mask PNGs, e.g. masks = \"masks\" "
                "(or a [target] table)")
    elif isinstance(data["masks"], str) and data["masks"].strip():
        d.masks_dir = root / data["masks"]
    else:
        bad("'masks' must be a folder path (a non-empty string)")

    if views is not None:
        d.view_patterns, d.patterns_origin = list(views), "--views"
    elif "views" in data:
        v = data["views"]
        if isinstance(v, list) and all(isinstance(p, str) and p for p in v):
            d.view_patterns, d.patterns_origin = list(v), f"views in {CONFIG_NAME}"
        else:
            bad("'views' must be a list of view names or glob patterns, e.g. views = [\"frame_0*\"]")


def _parse_sources(d: Draft, data: dict, bad) -> None:
    """[pre], [reference] and one [methods.NAME] per method (with its own [methods.NAME.pre])."""
    root = d.root
    if "pre" not in data:
        bad("missing required table [pre]: the original reconstruction, e.g. [pre] scene = \"pre.ply\"")
    else:
        d.pre = _parse_source(data["pre"], "[pre]", root, bad, depth_required=True)
    if "reference" in data:
        d.reference = _parse_source(data["reference"], "[reference]", root, bad, depth_required=False)
    methods = data.get("methods")
    if methods is None:
        bad("missing required table [methods.NAME]: one per evaluated method, e.g. [methods.mine] "
            "scene = \"mine.ply\"")
    elif not isinstance(methods, dict) or not methods:
        bad("'methods' must hold one table per method, e.g. [methods.mine] scene = \"mine.ply\"")
    else:
        for name, table in methods.items():
            if isinstance(table, dict) and "pre" in table:  # the method's own pre-removal source
                table = dict(table)
                d.method_pres[name] = _parse_source(table.pop("pre"), f"[methods.{name}.pre]", root, bad,
                                                    depth_required=True)
            d.methods[name] = _parse_source(table, f"[methods.{name}]", root, bad, depth_required=True,
                                            extra_keys=("pre",))


def _default_name(root: Path) -> str:
    return root.resolve().name


def _unknown_keys(table: dict, allowed: tuple[str, ...], where: str | None, bad) -> None:
    for key in table:
        if key in allowed:
            continue
        close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
        hint = f"did you mean '{close[0]}'?" if close else f"known keys: {', '.join(allowed)}"
        bad(f"unknown key '{key}'{f' in {where}' if where else ''} ({hint})")


def _parse_source(table, label: str, root: Path, bad, *, depth_required: bool,
                  extra_keys: tuple[str, ...] = ()) -> SourceSpec | None:
    if not isinstance(table, dict):
        bad(f"{label} must be a table, e.g. {label} scene = \"FILE.ply\" or renders = \"FOLDER\"")
        return None
    _unknown_keys(table, SOURCE_KEYS + extra_keys, label, bad)
    given = [k for k in ("scene", "renders", "rgb") if k in table]
    if len(given) != 1:
        found = f" (found {', '.join(given)})" if given else ""
        bad(f"{label} needs exactly one of 'scene' (a splat file) or 'renders' (a folder with rgb/ and "
            f"depth/){found}")
        return None
    key = given[0]
    value = table[key]
    if not (isinstance(value, str) and value.strip()):
        bad(f"{label} '{key}' must be a path (a non-empty string)")
        return None
    ok = True
    scale = 1.0
    if "depth_scale" in table:
        s = table["depth_scale"]
        if key == "scene":
            bad(f"{label} 'depth_scale' applies to renders only (a splat scene's depth is in scene units)")
            ok = False
        elif isinstance(s, bool) or not isinstance(s, (int, float)) or not math.isfinite(s) or s <= 0:
            bad(f"{label} 'depth_scale' must be a positive number, got {s!r}")
            ok = False
        else:
            scale = float(s)
    if "depth" in table and key != "rgb":
        bad(f"{label} 'depth' goes with 'rgb' (explicit folders); a renders folder's depth is its depth/ "
            f"sub-folder and a splat scene's depth is rendered")
        ok = False
    render = _parse_render_settings(table, label, bad, scene=key == "scene")
    frame = None
    if "frame" in table:
        if key != "scene":
            bad(f"{label} 'frame' applies to splat scenes only (renders are images already)")
            ok = False
        else:
            frame = _frame_value(table["frame"], f"{label} ", bad)
            ok = ok and frame is not None
    orbit = table.get("orbit")
    if orbit is not None:
        if key == "scene":
            bad(f"{label} 'orbit' applies to renders only (r360gpu renders a splat scene at the orbit itself)")
            ok = False
        elif not (isinstance(orbit, str) and orbit.strip()):
            bad(f"{label} 'orbit' must be a folder path (a non-empty string)")
            ok = False
    if not ok or render is None:
        return None
    if key == "scene":
        return SourceSpec("scene", root / value, render=render, frame=frame)
    if key == "renders":
        folder = root / value
        depth = folder / "depth"
        if not depth_required and not depth.exists():
            depth = None
        spec = SourceSpec("renders", folder, scale, folder / "rgb", depth)
    else:
        rgb = root / value
        depth = table.get("depth")
        if depth is not None and not (isinstance(depth, str) and depth.strip()):
            bad(f"{label} 'depth' must be a folder path (a non-empty string)")
            return None
        spec = SourceSpec("renders", rgb, scale, rgb, None if depth is None else root / depth)
    if orbit is None:
        return spec
    # laid out as a renders folder; depth there whenever the source has depth at the capture views
    folder = root / orbit
    return replace(spec, orbit=SourceSpec("renders", folder, scale, folder / "rgb",
                                          None if spec.depth_dir is None else folder / "depth"))


def _parse_render_settings(table: dict, label: str, bad, *, scene: bool) -> RenderSettings | None:
    """The render keys of a source table (None after reporting a problem)."""
    given = [k for k in RENDER_KEYS if k in table]
    if given and not scene:
        bad(f"{label} {', '.join(repr(k) for k in given)} apply to splat scenes only (renders are images already)")
        return None
    ok = True

    def number(v) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    if "antialiased" in table and not isinstance(table["antialiased"], bool):
        bad(f"{label} 'antialiased' must be true or false, got {table['antialiased']!r}")
        ok = False
    if "near" in table and not (number(table["near"]) and table["near"] > 0):
        bad(f"{label} 'near' must be a positive number (INRIA 0.2, gsplat 0.01), got {table['near']!r}")
        ok = False
    if "no_coverage_alpha" in table and not (number(table["no_coverage_alpha"])
                                             and 0 <= table["no_coverage_alpha"] <= 1):
        bad(f"{label} 'no_coverage_alpha' must be a number in [0, 1], got {table['no_coverage_alpha']!r}")
        ok = False
    if "principal_point" in table and table["principal_point"] not in PRINCIPAL_POINTS:
        bad(f"{label} 'principal_point' must be {' or '.join(map(repr, PRINCIPAL_POINTS))}, "
            f"got {table['principal_point']!r}")
        ok = False
    if not ok:
        return None
    return RenderSettings(**{k: (float(table[k]) if k in ("near", "no_coverage_alpha") else table[k]) for k in given})


def _frame_value(value, label: str, bad) -> str | None:
    """A ``frame`` key's value (None after reporting a problem); resolved once the cameras are known."""
    from ..io.frames import FRAME_KEYWORDS

    if isinstance(value, str) and value.strip():
        return value.strip()
    bad(f"{label}'frame' must be {', '.join(map(repr, FRAME_KEYWORDS))} or the path of a nerfstudio "
        f"dataparser_transforms.json, got {value!r}")
    return None


def _parse_options(table, bad) -> BundleOptions:
    opts = BundleOptions()
    if not isinstance(table, dict):
        bad("[options] must be a table")
        return opts
    _unknown_keys(table, OPTION_KEYS, "[options]", bad)
    if "background" in table:
        bg = table["background"]
        if (isinstance(bg, list) and len(bg) == 3
                and all(isinstance(c, (int, float)) and not isinstance(c, bool) and 0 <= c <= 1 for c in bg)):
            opts.background = tuple(float(c) for c in bg)
        else:
            bad(f"[options] 'background' must be three numbers in [0, 1] (RGB), got {bg!r}")
    if "depth" in table:
        mode = table["depth"]
        if mode in DEPTH_MODES:
            opts.depth = mode
        else:
            close = difflib.get_close_matches(str(mode), DEPTH_MODES, n=1, cutoff=0.6)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            bad(f"[options] 'depth' must be {' or '.join(map(repr, DEPTH_MODES))}, got {mode!r}{hint}")
    if "reference_free" in table:
        if isinstance(table["reference_free"], bool):
            opts.reference_free = table["reference_free"]
        else:
            bad(f"[options] 'reference_free' must be true or false, got {table['reference_free']!r}")
    return opts

