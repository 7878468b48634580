"""Build probes from command-line specs: :func:`parse_probe_spec`.

One place for every probe name: the weight-free built-ins (``builtin``,
``builtin-appearance``, ``builtin-hierarchy``, ``builtin-graphseg``, ``builtin-slic``: plain names,
see :data:`BUILTIN_PROBES`), the default probe of each axis
(:data:`DEFAULT_PROBES`, :func:`default_probes`), and the model / file probes
with spec syntax ``KIND:BODY``; :func:`probe_for_axis` builds the probe a
command-line spec names for one axis.

* ``sam:encoder=PATH,decoder=PATH[,device=D][,name=N][,AMG_PARAM=VALUE...]``
  -- :class:`~r360gpu.probes.sam_amg.SamAmgProbe` (structural).  AMG_PARAM is
  any :class:`~r360gpu.probes.sam_amg.AmgParams` field, e.g.
  ``points_per_side=16``, ``pred_iou_thresh=0.9``, ``crop_n_layers=1``,
  ``min_mask_region_area=100``.
* ``grounded:dino=PATH,tokenizer=PATH,sam-encoder=PATH,sam-decoder=PATH
  [,device=D][,name=N][,box_threshold=F][,text_threshold=F][,resize=S/M|WxH]
  [,size=I][,max_size=I][,phrase_match=true|false]`` --
  :class:`~r360gpu.probes.grounded.GroundedSamProbe` (semantic).  tokenizer
  is a ``tokenizer.json`` or a BERT ``vocab.txt``; ``resize=800/1333``
  (default: shorter side 800, longer at most 1333, as GroundingDINO) or
  ``resize=1200x800`` (exactly 1200 wide, 800 high, as common ONNX runtimes).
* ``gsam2-json:DIRS``, ``png:DIRS`` -- precomputed semantic masks
  (:class:`~r360gpu.probes.precomputed.PrecomputedSemanticProbe`);
  ``sam-json:DIRS`` -- precomputed SAM masks
  (:class:`~r360gpu.probes.precomputed.PrecomputedStructuralProbe`).
  DIRS is either ``pre=DIR,post=DIR[,ref=DIR][,name=N]`` or one directory
  holding a sub-directory per rendering, named ``pre`` / ``before``,
  ``post`` / ``after``, ``ref`` / ``reference`` (for ``png``, a ``mask``
  folder inside it is used when present: the Remove360 layout
  ``gsam2/before/mask``).  With several methods, each method's post masks
  go in ``post/METHOD/`` (a sub-folder of the post folder named like the
  method) or ``post/METHOD=DIR`` in the explicit form; plain ``post``
  serves the methods without their own folder.
  DIRS may also be the root of a folder in the public Remove360 layout
  (:data:`PUBLIC_LAYOUT`): ``png:ROOT`` / ``gsam2-json:ROOT`` read
  ``ROOT/gsam2/{before,after}`` (``mask/`` inside for png), ``sam-json:ROOT``
  reads ``ROOT/sam/after`` for post and ``ROOT/sam/before`` for pre when it
  exists, else the SAM JSON the public download keeps in ``ROOT/masks``
  (SAM on the captured pre-removal photos, the public scripts' "GT" side).

Public folders' own outputs are the default probes of such a folder
(:func:`scene_probes`): without probes given and without ``--compat``, a
Remove360-layout bundle with ``gsam2/`` uses its GSAM2 masks on the
semantic axis and one with ``sam/after`` (and pre-side SAM JSON) its SAM
masks on the structural axis; what was chosen and why is returned for the
console and results.json.

Keys may use '-' or '_'.  Values cannot contain ','.  device is one of
cpu, cuda, tensorrt, webgpu, directml, coreml, auto
(:mod:`r360gpu.probes.providers`); without it, the ``device`` given to
:func:`parse_probe_spec` / :func:`probe_for_axis` (``--probe-device``), else cpu.  Booleans: true/false, yes/no,
1/0.  Any problem is an InputError naming the spec.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from r360gpu.errors import InputError
from r360gpu.probes.base import Probe

__all__ = [
    "PROBE_KINDS",
    "BUILTIN_PROBES",
    "DEFAULT_PROBES",
    "PROBE_SPEC_HELP",
    "parse_probe_spec",
    "builtin_probe",
    "default_probes",
    "probe_for_axis",
]

PROBE_KINDS = ("sam", "grounded", "gsam2-json", "png", "sam-json")

#: Built-in probe name -> (axis, what it is).  ``builtin`` is the axis default.
BUILTIN_PROBES = {
    "builtin-appearance": ("semantic", "weight-free appearance probe fitted on the scene's pre renderings"),
    "builtin-hierarchy": ("structural", "weight-free multi-level segmentation (whole, part, sub-part)"),
    "builtin-graphseg": ("structural", "weight-free graph segmentation"),
    "builtin-slic": ("structural", "weight-free SLIC superpixels"),
}
#: The probe each axis uses when none is given.
DEFAULT_PROBES = {"semantic": "builtin-appearance", "structural": "builtin-hierarchy"}

PROBE_SPEC_HELP = (
    "probe name builtin (the axis default), "
    + ", ".join(BUILTIN_PROBES)
    + "; or probe spec KIND:BODY -- sam:encoder=PATH,decoder=PATH[,device=auto|cpu|cuda|tensorrt|webgpu|directml|coreml][,AMG params]; "
    "grounded:dino=PATH,tokenizer=tokenizer.json|vocab.txt,sam-encoder=PATH,sam-decoder=PATH"
    "[,box_threshold=0.35,text_threshold=0.25,resize=800/1333|1200x800]; "
    "gsam2-json:DIR, png:DIR, sam-json:DIR (DIR with pre/post/ref or before/after sub-folders) "
    "or KIND:pre=DIR,post=DIR[,ref=DIR]"
)

_RENDERING_DIRS = {"pre": ("pre", "before"), "post": ("post", "after"), "ref": ("ref", "reference")}
#: Where a public Remove360-layout folder keeps the scripts' probe outputs, per spec kind and
#: rendering (candidates in order; the first existing one is used).
PUBLIC_LAYOUT = {
    "png": {"pre": ("gsam2/before/mask",), "post": ("gsam2/after/mask",), "ref": ("gsam2/reference/mask",)},
    "gsam2-json": {"pre": ("gsam2/before",), "post": ("gsam2/after",), "ref": ("gsam2/reference",)},
    "sam-json": {"pre": ("sam/before", "masks"), "post": ("sam/after",), "ref": ("sam/reference",)},
}
_TRUE = {"true", "yes", "1", "on"}
_FALSE = {"false", "no", "0", "off"}


def builtin_probe(name: str) -> Probe:
    """A new built-in probe by its name in :data:`BUILTIN_PROBES`."""
    if name == "builtin-appearance":
        from r360gpu.probes.builtin_semantic import BuiltinAppearanceProbe

        return BuiltinAppearanceProbe()
    from r360gpu.probes.builtin_structural import BuiltinStructuralProbe, StructuralParams

    if name == "builtin-hierarchy":
        return BuiltinStructuralProbe()
    if name == "builtin-graphseg":
        return BuiltinStructuralProbe(StructuralParams.graph())
    if name == "builtin-slic":
        return BuiltinStructuralProbe(StructuralParams.slic())
    raise InputError(f"unknown built-in probe {name!r} (built-ins: {', '.join(BUILTIN_PROBES)})")


def default_probes() -> tuple[list[Probe], list[Probe]]:
    """New default probes: ([semantic], [structural]) (:data:`DEFAULT_PROBES`)."""
    return [builtin_probe(DEFAULT_PROBES["semantic"])], [builtin_probe(DEFAULT_PROBES["structural"])]


def probe_for_axis(spec: str, axis: str, device: str = "cpu") -> Probe:
    """The probe a command-line spec names for one axis ("semantic" or "structural").

    ``builtin`` is the axis default; a built-in name or a ``KIND:BODY`` spec
    must give a probe of that axis (else InputError naming the spec).  device:
    the onnxruntime device of a learned probe whose spec gives none.
    """
    if axis not in DEFAULT_PROBES:
        raise ValueError(f"axis must be one of {sorted(DEFAULT_PROBES)}, got {axis!r}")
    name = str(spec).strip().lower()
    if name == "builtin":
        name = DEFAULT_PROBES[axis]
    if name in BUILTIN_PROBES:
        if BUILTIN_PROBES[name][0] != axis:
            raise InputError(f"probe spec {spec!r} is a {BUILTIN_PROBES[name][0]} probe, not a {axis} one")
        return builtin_probe(name)
    probe = parse_probe_spec(spec, device)
    if probe.kind != axis:
        raise InputError(f"probe spec {spec!r} gives a {probe.kind} probe, but --{axis}-probe needs a {axis} one")
    return probe


def parse_probe_spec(spec: str, device: str = "cpu") -> Probe:
    """The probe a spec describes (see the module docstring); device: a learned probe's
    onnxruntime device when the spec gives none."""
    text = str(spec).strip()
    kind, sep, body = text.partition(":")
    kind = kind.strip().lower()
    if not sep or kind not in PROBE_KINDS:
        raise InputError(f"probe spec {spec!r}: expected KIND:..., KIND one of {', '.join(PROBE_KINDS)}")
    if not body.strip():
        raise InputError(f"probe spec {spec!r}: nothing after '{kind}:'")
    if kind == "sam":
        return _sam(spec, _options(spec, body), device)
    if kind == "grounded":
        return _grounded(spec, _options(spec, body), device)
    return _precomputed(spec, kind, body)


def _key(raw: str) -> str:
    return raw.strip().lower().replace("-", "_")


def _options(spec: str, body: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for part in body.split(","):
        if not part.strip():
            continue
        key, eq, value = part.partition("=")
        if not eq or not key.strip():
            raise InputError(f"probe spec {spec!r}: {part.strip()!r} is not KEY=VALUE")
        key = _key(key)
        if key in out:
            raise InputError(f"probe spec {spec!r}: {key!r} is given twice")
        out[key] = value.strip()
    return out


def _take_required(spec: str, opts: dict[str, str], keys: tuple[str, ...]) -> list[str]:
    missing = [k for k in keys if not opts.get(k)]
    if missing:
        raise InputError(f"probe spec {spec!r}: missing {', '.join(k.replace('_', '-') for k in missing)}")
    return [opts.pop(k) for k in keys]


def _convert(spec: str, key: str, value: str, type_name: str) -> object:
    """A spec value converted to a dataclass field's type.

    type_name: the field's annotation text ("int", "float", "bool", "str", or
    one of those with "| None", which also accepts "none" / "default").
    """
    kind = type_name.replace(" ", "")
    if kind.endswith("|None"):
        kind = kind[: -len("|None")]
        if value.lower() in ("none", "default"):
            return None
    try:
        if kind == "bool":
            if value.lower() in _TRUE:
                return True
            if value.lower() in _FALSE:
                return False
        elif kind == "int":
            return int(value)
        elif kind == "float":
            return float(value)
        else:
            return value
    except ValueError:
        pass
    raise InputError(f"probe spec {spec!r}: {key}={value!r} is not a valid {kind}")


def _dataclass_kwargs(spec: str, opts: dict[str, str], cls) -> dict:
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key in list(opts):
        if key in fields:
            annotation = fields[key].type
            type_name = annotation if isinstance(annotation, str) else getattr(annotation, "__name__", str(annotation))
            kwargs[key] = _convert(spec, key, opts.pop(key), type_name)
    if opts:
        allowed = ", ".join(sorted(fields))
        raise InputError(f"probe spec {spec!r}: unknown option(s) {', '.join(sorted(opts))} (options: {allowed})")
    return kwargs


def _sam(spec: str, opts: dict[str, str], device: str) -> Probe:
    from r360gpu.probes.sam_amg import AmgParams, SamAmgProbe

    encoder, decoder = _take_required(spec, opts, ("encoder", "decoder"))
    device = opts.pop("device", None) or device
    name = opts.pop("name", None) or None
    params = AmgParams(**_dataclass_kwargs(spec, opts, AmgParams))
    return SamAmgProbe(encoder, decoder, params=params, device=device, name=name)


def _grounded(spec: str, opts: dict[str, str], device: str) -> Probe:
    from r360gpu.probes.grounded import GroundedSamProbe, GroundingParams

    dino, tokenizer, encoder, decoder = _take_required(spec, opts, ("dino", "tokenizer", "sam_encoder", "sam_decoder"))
    device = opts.pop("device", None) or device
    name = opts.pop("name", None) or None
    params = GroundingParams(**_dataclass_kwargs(spec, opts, GroundingParams))
    return GroundedSamProbe(dino, tokenizer, encoder, decoder, params=params, device=device, name=name)


def _rendering_dirs(spec: str, kind: str, body: str) -> tuple[dict[str, Path], str | None]:
    first = body.split(",")[0]
    key = _key(first.partition("=")[0]) if "=" in first else ""
    if key in ("pre", "post", "ref", "name") or first.strip().lower().startswith("post/"):
        # post/METHOD=DIR: masks of one method's edit (method name kept as written).
        per_method = {}
        rest = []
        for part in body.split(","):
            k, eq, v = part.partition("=")
            if eq and k.strip().lower().startswith("post/") and k.strip()[5:]:
                per_method[f"post/{k.strip()[5:]}"] = v.strip()
            else:
                rest.append(part)
        opts = _options(spec, ",".join(rest))
        opts.update(per_method)
        name = opts.pop("name", None) or None
        unknown = sorted(k for k in set(opts) - set(_RENDERING_DIRS) if not k.startswith("post/"))
        if unknown:
            raise InputError(f"probe spec {spec!r}: unknown key(s) {', '.join(unknown)} (use pre, post, ref, name)")
        dirs = {r: Path(d) for r, d in opts.items() if d}
        if not dirs:
            raise InputError(f"probe spec {spec!r}: give at least one of pre=DIR, post=DIR, ref=DIR")
        return dirs, name
    root = Path(body.strip())
    if not root.is_dir():
        raise InputError(f"probe spec {spec!r}: mask directory does not exist; give a folder with pre/ and post/ "
                         f"(or before/ and after/) sub-folders, a public Remove360 folder's root, or name them: "
                         f"{kind}:pre=DIR,post=DIR", root)
    dirs: dict[str, Path] = {}
    for rendering, names in _RENDERING_DIRS.items():
        for sub in names:
            if (root / sub).is_dir():
                dirs[rendering] = root / sub
                break
    if not dirs:
        dirs = public_dirs(root, kind)
        if dirs:
            return dirs, None
        wanted = ", ".join("/".join(n) for n in _RENDERING_DIRS.values())
        public = ", ".join(sorted({c for cs in PUBLIC_LAYOUT[kind].values() for c in cs}))
        raise InputError(
            f"probe spec {spec!r}: no per-rendering sub-folder ({wanted}) and not a public Remove360 folder "
            f"({public}); a spec that works: {_working_spec(root, kind)}", root)
    if "pre" not in dirs and "ref" not in dirs:  # post masks alone are compared with nothing
        parent = root.parent
        works = (f"{kind}:{parent} (the public folder's root)" if public_dirs(parent, kind)
                 else f"{kind}:pre=DIR,post={dirs['post']}" if "post" in dirs else _working_spec(root, kind))
        raise InputError(f"probe spec {spec!r}: only {', '.join(f'{r} masks ({d})' for r, d in dirs.items())}; the "
                         f"axes compare them with pre (or ref) masks; a spec that works: {works}", root)
    # A bundle with several methods keeps each method's post masks in a
    # sub-folder of the post folder named like the method (post/<method>/).
    post = dirs.get("post")
    if post is not None:
        from r360gpu.probes.amg_folders import is_amg_view_folder

        # (SAM amg.py output holds one folder per view, with metadata.csv: not method folders.)
        for sub in sorted(p for p in post.iterdir() if p.is_dir() and p.name != "mask"
                          and not is_amg_view_folder(p)):
            dirs[f"post/{sub.name}"] = sub
    if kind == "png":
        dirs = {r: (d / "mask" if (d / "mask").is_dir() else d) for r, d in dirs.items()}
    return dirs, None


def public_dirs(root: Path, kind: str) -> dict[str, Path]:
    """{rendering: folder} of the probe outputs a public Remove360-layout folder holds for spec
    ``kind`` (:data:`PUBLIC_LAYOUT`); {} unless both pre and post are there."""
    root = Path(root)
    found = {}
    for rendering, candidates in PUBLIC_LAYOUT[kind].items():
        for rel in candidates:
            d = root / rel
            if d.is_dir() and (kind != "sam-json" or any(d.glob("*.json")) or _has_amg_folders(d)):
                found[rendering] = d
                break
    return found if "pre" in found and "post" in found else {}


def _has_amg_folders(d: Path) -> bool:
    from r360gpu.probes.amg_folders import is_amg_view_folder

    return any(p.is_dir() and is_amg_view_folder(p) for p in d.iterdir())


def _working_spec(root: Path, kind: str) -> str:
    """A spec of ``kind`` naming folders under ``root`` that hold mask files (for error messages)."""
    suffix = "*.png" if kind == "png" else "*.json"
    holders = sorted({p.parent for p in root.rglob(suffix)}, key=lambda p: (len(p.parts), str(p)))[:2]
    if len(holders) == 2:
        return f"{kind}:pre={holders[0]},post={holders[1]} (check which folder is which rendering)"
    return f"{kind}:pre=DIR,post=DIR (folders of <view>{suffix[1:]} files)"


def _precomputed(spec: str, kind: str, body: str) -> Probe:
    from r360gpu.probes.precomputed import PrecomputedSemanticProbe, PrecomputedStructuralProbe

    dirs, name = _rendering_dirs(spec, kind, body)
    for rendering, d in dirs.items():
        if not Path(d).is_dir():
            raise InputError(f"probe spec {spec!r}: the {rendering} mask folder does not exist; a spec that works: "
                             f"{kind}:pre=DIR,post=DIR with existing folders", d)
    if kind == "sam-json":
        return PrecomputedStructuralProbe.from_dirs(dirs, **({"name": name} if name else {}))
    return PrecomputedSemanticProbe.from_dirs(dirs, format=kind, **({"name": name} if name else {}))


# --- the probes of one scene -----------------------------------------------------------------------

#: What a public folder's outputs are, per axis (for the console and results.json).
_FOLDER_OUTPUTS = {"semantic": ("png", "GSAM2 masks"), "structural": ("sam-json", "SAM masks")}


def scene_probes(bundle, semantic: list | None, structural: list | None, *, compat=None, defaults=None):
    """The probes one scene is scored with, and why: ``(semantic, structural, selection)``.

    semantic / structural: the probes the caller gave (None: not given).
    Not given, a bundle in the public Remove360 layout (without ``compat``)
    uses the probe outputs it holds (:func:`public_dirs`), else the axis
    default (``defaults``: ([semantic], [structural]) already built, else
    :func:`default_probes`).  selection: {axis: {"probes": [names],
    "source": "command line" | "folder" | "default", "why": str}}.
    """
    given = {"semantic": semantic, "structural": structural}
    fallback: dict = {}  # built when an axis needs it: the built-ins import scipy.ndimage
    out, selection = {}, {}
    for axis in ("semantic", "structural"):
        if given[axis] is not None:
            out[axis] = list(given[axis])
            selection[axis] = {"source": "command line", "why": "given by the caller"}
            continue
        probe, why = _folder_probe(bundle, axis, compat)
        if probe is not None:
            out[axis] = [probe]
            selection[axis] = {"source": "folder", "why": why}
        else:
            fallback = fallback or dict(zip(("semantic", "structural"), defaults or default_probes()))
            out[axis] = list(fallback[axis])
            selection[axis] = {"source": "default", "why": why}
    for axis in out:
        selection[axis] = {"probes": [p.name for p in out[axis]], **selection[axis]}
    return out["semantic"], out["structural"], selection


def _folder_probe(bundle, axis: str, compat) -> tuple[Probe | None, str]:
    """The probe built from a public folder's outputs for ``axis`` (or None) and why."""
    kind, what = _FOLDER_OUTPUTS[axis]
    default = f"the weight-free default ({DEFAULT_PROBES[axis]})"
    if getattr(bundle, "layout", None) != "remove360":
        return None, f"{default}: no probe given"
    root = Path(bundle.root)
    dirs = public_dirs(root, kind)
    if not dirs:
        wanted = " and ".join(f"{r} {'/'.join(c)}" for r, c in PUBLIC_LAYOUT[kind].items() if r != "ref")
        return None, f"{default}: the folder has no {what} ({wanted})"
    spec = f"--{axis}-probe {kind}:{root}"
    if compat:
        return None, (f"{default}: with --compat the public scripts' numbers replace the axes, and the probes stay "
                      f"as without the folder's outputs so --compat results do not change ({spec} uses them)")
    if bundle.reference is not None and "ref" not in dirs:  # (the reference control reads it in every mode)
        return None, (f"{default}: the folder has a reference (rgb/reference) but no {what} for it "
                      f"({PUBLIC_LAYOUT[kind]['ref'][0]})")
    from r360gpu.probes.precomputed import PrecomputedSemanticProbe, PrecomputedStructuralProbe

    if axis == "semantic":
        probe = PrecomputedSemanticProbe.from_dirs(dirs, format=kind, name="gsam2-folder")
    else:
        probe = PrecomputedStructuralProbe.from_dirs(dirs, name="sam-folder")
    shown = ", ".join(f"{r}={Path(d).relative_to(root).as_posix()}" for r, d in sorted(dirs.items()))
    if Path(dirs["pre"]).name == "masks":
        shown += ": pre is SAM on the captured pre-removal photos, the side the public scripts compare with"
    return probe, (f"the folder's {what} found in {root} ({shown}); the public scripts' own probe outputs are "
                   f"used by default (--{axis}-probe builtin for the weight-free probe)")
