"""A folder in the public Remove360 evaluation layout, read as a bundle (no scene.toml).

The layout of the public evaluation code (github.com/simonakocour/anything_left,
``scripts/run_pipeline.py`` and ``scripts/download_dataset.py``), one folder
per scene and removed object (``{scene}_{object}``, e.g. ``bedroom_table``)::

    rgb/before/<view>.png|jpg    the method's renderings BEFORE removal   -> I_pre   ("pre")
    rgb/after/<view>.png|jpg     the method's renderings AFTER removal    -> I_post  (the method)
    depth/before/<view>.png      depth renderings before removal          -> D_pre
    depth/after/<view>.png       depth renderings after removal           -> D_post
    masks/<view>.png             ground-truth target masks M^v (the dataset's "masks")
    images/before/, images/after/  the dataset's CAPTURED photos (its train/ and test/
                                 splits: the pre-removal and the physical post-removal
                                 captures)

What r360gpu takes from it, and why:

* pre = ``rgb/before`` + ``depth/before``; one method = ``rgb/after`` +
  ``depth/after``, named "after" unless a name is given.
* The evaluation views are the masks' names, as in the public code (which
  iterates ``masks/*.png``).  ``masks/`` may also hold the public code's SAM
  outputs (``*.json``); only PNGs are masks.
* Depth: the public code writes and reads PNGs (it converts them to 8-bit grey
  before differencing); r360gpu reads them at full precision (8- or 16-bit)
  and also accepts .exr/.npy/.tiff (see :mod:`r360gpu.io.renders`).  Units
  are whatever the renderer wrote, the same for before and after, which is all
  the per-view GHT threshold needs.
* ``images/`` is not used.  They are captured photos, not renderings: the
  pre-removal photos are posed like the views but are not what the
  reconstruction renders, and the post-removal photos come from a separate
  capture with independently estimated poses, so neither is the paper's
  I_ref (the post-removal *reconstruction* rendered at the evaluation pose).
  (The public code runs SAM on ``images/before`` for its sim_SAM "GT" masks;
  r360gpu follows the paper instead.)  Without a reference the structural
  axis is reference-free: s_str = 1 - sim_SAM(I_pre, I_post).
* r360gpu extension: pose-matched reference renderings, if you have them, go
  in ``rgb/reference/`` (and optionally ``depth/reference/``).
* Prompt: the ``prompt`` argument (``--prompt``), else the first line of
  ``prompt.txt`` in the folder; there is no default (the folder name's last
  word is only suggested in the error message).
"""
from __future__ import annotations

from pathlib import Path

from .model import Draft, Problem, SourceSpec

DEFAULT_METHOD_NAME = "after"
PROMPT_FILE = "prompt.txt"
LAYOUT_DIRS = ("rgb/before", "rgb/after", "depth/before", "depth/after", "masks", "images/before", "images/after")


def is_remove360_folder(root: Path) -> bool:
    """True when ``root`` looks like the public Remove360 layout: it has ``rgb/`` or
    ``depth/``, or both ``masks/`` and ``images/`` (a freshly downloaded scene)."""
    root = Path(root)
    return (root / "rgb").is_dir() or (root / "depth").is_dir() or (
        (root / "masks").is_dir() and (root / "images").is_dir())


def remove360_draft(root: Path, *, prompt: str | None, method_name: str | None,
                    problems: list[Problem]) -> Draft:
    """The declared bundle of a Remove360-layout folder; problems found on the way
    (no prompt, unreadable prompt.txt) are appended to ``problems``.  Files and
    folders are checked later, with every other bundle."""
    root = Path(root)
    draft = Draft(root=root, layout="remove360", name=root.resolve().name)
    from ..util.warning_log import where

    with where(scene=draft.name):  # a warning about prompt.txt names the scene
        draft.prompt = _prompt(root, prompt, problems)
    draft.masks_dir = root / "masks"
    draft.pre = _renders(root, "before", depth_required=True)
    draft.methods[method_name if method_name is not None else DEFAULT_METHOD_NAME] = _renders(
        root, "after", depth_required=True)
    if (root / "rgb" / "reference").is_dir():
        draft.reference = _renders(root, "reference", depth_required=False)
    return draft


def _renders(root: Path, which: str, *, depth_required: bool) -> SourceSpec:
    rgb = root / "rgb" / which
    depth = root / "depth" / which
    if not depth_required and not depth.exists():
        depth = None
    return SourceSpec("renders", rgb, 1.0, rgb, depth)


def _prompt(root: Path, prompt: str | None, problems: list[Problem]) -> str | None:
    if prompt is not None:
        if not prompt.strip():
            problems.append(Problem(None, "the prompt given is empty"))
            return None
        return prompt.strip()
    file = root / PROMPT_FILE
    if file.is_file():
        try:
            text = file.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            problems.append(Problem(str(file), f"cannot read the prompt: {getattr(e, 'strerror', None) or e}"))
            return None
        if "\ufeff" in text:  # a byte-order mark (Windows editors) would become part of the prompt
            from ..util.warning_log import warn

            text = text.replace("\ufeff", "")
            warn("prompt file holds a byte-order mark (U+FEFF); removed from the prompt", file=file)
        lines = [line.strip() for line in text.splitlines() if line.strip()]
        if not lines:
            problems.append(Problem(str(file), "prompt file is empty"))
            return None
        return lines[0]
    guess = root.resolve().name.rsplit("_", 1)[-1]
    problems.append(Problem(str(file), f"no prompt: write the removed object's category (e.g. {guess!r}) "
                                       f"into {PROMPT_FILE}, or pass --prompt"))
    return None


def without_depth(bundle):
    """The bundle with no depth folders attached to its sources (a copy).

    The ``--compat`` modes score a public folder's depth as the public scripts
    read it (:mod:`r360gpu.metrics.compat_public`: PIL ``convert("L")``, which
    also takes RGB and palette PNGs), so the scoring pipeline must not read
    those PNGs as r360gpu's float depth.  Bundles of another layout are
    returned unchanged.
    """
    import dataclasses

    if getattr(bundle, "layout", None) != "remove360":
        return bundle
    strip = lambda s: None if s is None else dataclasses.replace(s, depth_dir=None)  # noqa: E731
    return dataclasses.replace(bundle, pre=strip(bundle.pre), reference=strip(bundle.reference),
                               methods={m: strip(s) for m, s in bundle.methods.items()})
