"""The one check of every name that becomes a path or a key: scene, method and view names.

Scene names name output folders (``OUT/pictures/<scene>/``) and cache
folders; method names name output folders and cache cells, and share one
namespace with the bundle's other sources (``pre``, ``reference``: the
controls' cells are cached under those names); view names name picture and
cache files.  A name that holds a path separator or ``..`` would write
outside ``--out``; two names that differ only in case collide on
case-insensitive file systems (macOS, Windows) and in the cache.

scene.toml (:mod:`.load`), ``METHOD=FOLDER`` pairs and benchmark folders
(:mod:`.group`), :func:`~r360gpu.bundle.scene_from_objects` and
:func:`r360gpu.evaluate` all call :func:`name_problems`, so the CLI and the
library accept exactly the same names (tests/test_names.py feeds one table
of hostile names through all of them).
"""
from __future__ import annotations

from typing import Iterable

from ..errors import InputError

# Names of the non-method sources; a method may not use them (case-insensitive):
# outputs and records key methods and these sources in one namespace.
RESERVED_METHOD_NAMES = ("pre", "reference")
#: Suffixes r360gpu adds to a method's name for the outputs it derives from it (``--prune-residuals``:
#: the what-if METHOD+pruned, its residuals/SCENE/METHOD+pruned.ply); a method may not be named like
#: another one's derived output (case-insensitive), which would overwrite it.
DERIVED_SUFFIXES = ("+pruned",)
# Windows device names: a folder called CON or NUL cannot be created there.
_DEVICE_NAMES = {"con", "prn", "aux", "nul", *(f"com{i}" for i in range(1, 10)), *(f"lpt{i}" for i in range(1, 10))}
# ...nor a file name holding one of these characters (the outputs of a run must copy to any system).
_WINDOWS_FORBIDDEN = '<>:"|?*'
_MAX_LEN = 200  # file names are at most 255 bytes on common file systems; leave room for suffixes


def bad_name(name) -> str | None:
    """Why ``name`` cannot name an output file or folder, or None when it can."""
    if not isinstance(name, str):
        return f"is a {type(name).__name__}, not a string"
    if not name.strip():
        return "is empty"
    if name in (".", "..") or ".." in name.replace("\\", "/").split("/"):
        return "is not a usable name"
    if "/" in name or "\\" in name:
        return "contains a path separator"
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        return "contains control characters"
    if name != name.strip():
        return "has leading or trailing spaces"
    if name.split(".")[0].lower() in _DEVICE_NAMES:
        return "is a reserved device name on Windows"
    if any(c in _WINDOWS_FORBIDDEN for c in name):
        return f"contains a character Windows file names cannot hold ({' '.join(_WINDOWS_FORBIDDEN)})"
    if len(name.encode("utf-8", "surrogatepass")) > _MAX_LEN:
        return f"is longer than {_MAX_LEN} bytes"
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        return "is not valid Unicode text"
    return None


def name_problems(what: str, names: Iterable, *, reserved: tuple[str, ...] = ()) -> list[str]:
    """Every problem of a list of names of one kind (``what``: "scene", "method", "view"):
    unusable names, reserved ones (case-insensitive) and names that differ only in case."""
    problems: list[str] = []
    seen: dict[str, str] = {}
    for name in names:
        reason = bad_name(name)
        if reason:
            problems.append(f"{what} name {name!r} {reason} (it names output files)")
            continue
        if name.casefold() in reserved:
            problems.append(f"{what} name {name!r} is reserved (the bundle's {', '.join(reserved)} sources); "
                            f"rename it")
        key = name.casefold()
        if key in seen:
            problems.append(f"duplicate {what} name: {seen[key]!r} and {name!r} differ only in case (their "
                            f"output files would collide)")
        else:
            seen[key] = name
    if what == "method":
        for key, name in seen.items():
            for suffix in DERIVED_SUFFIXES:
                if key.endswith(suffix) and key[: -len(suffix)] in seen:
                    base = seen[key[: -len(suffix)]]
                    problems.append(f"method name {name!r} is the name r360gpu gives method {base!r}'s pruned "
                                    f"what-if (score --prune-residuals writes residuals/SCENE/{base}{suffix}.ply); "
                                    f"rename it")
    return problems


def check_names(what: str, names: Iterable, *, reserved: tuple[str, ...] = (), path=None) -> None:
    """InputError listing every problem of :func:`name_problems` (nothing when the names are usable)."""
    problems = name_problems(what, list(names), reserved=reserved)
    if problems:
        raise InputError("; ".join(problems), path)


def check_bundle_names(bundle) -> None:
    """The names of a bundle built anywhere (scene.toml, a public folder, objects, by hand):
    scene, methods (not reserved, not equal ignoring case) and views."""
    check_names("scene", [bundle.name])
    check_names("method", list(bundle.methods), reserved=RESERVED_METHOD_NAMES)
    problems = name_problems("view", list(bundle.views))
    if problems:
        listed = "; ".join(problems[:5]) + (f"; and {len(problems) - 5} more" if len(problems) > 5 else "")
        raise InputError(f"scene {bundle.name!r}: {listed}")
