"""A bundle's sources checked on disk: splat scene files (format, header, size; with ``deep`` the
loader ``score`` uses) and rendering folders (an RGB and depth file of every view, of the mask's
size; with ``deep`` decoded by the readers ``score`` uses)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.cameras_json import load_cameras_json
from ..io.compressed_ply import check_compressed_header, is_compressed_ply
from ..io.inria_ply import check_inria_header, is_inria_ply
from ..io.load import latest_inria_iteration, load_gaussians
from ..io.paths import link_problem
from ..io.ply import read_ply_header
from ..io.renders import RendersReader, depth_size, image_size, read_depth, read_rgb
from .model import ORBIT_CAMERAS, Draft, Problem, SourceSpec, add_capped, listed_names

_SPLAT_RECORD_BYTES = 32
_PLY_MAGIC = (b"ply\n", b"ply\r\n")


def check_scene(spec: SourceSpec, label: str, problems: list[Problem], *, deep: bool = False) -> SourceSpec | None:
    """The scene source with its path resolved (an INRIA output folder -> its latest iteration's PLY),
    or None after appending why the file is not a loadable splat scene (``label`` names the source)."""
    p = Path(spec.path)
    try:
        if not p.exists():
            raise InputError(f"scene file is a {link_problem(p)}" if link_problem(p) else "no such file", p)
        if p.is_dir():
            p = latest_inria_iteration(p)
        suffix = p.suffix.lower()
        if suffix == ".splat":
            _check_splat(p)
        elif suffix == ".ply" or _starts_with(p, _PLY_MAGIC):
            _check_ply(p)
        else:
            raise InputError("unknown Gaussian-splat format; expected an INRIA 3DGS .ply, a .compressed.ply "
                             "or a .splat file", p)
        if deep:  # the loader score uses, with its checks (e.g. every Gaussian NaN): check OK = score loads it
            load_gaussians(p)
    except InputError as e:
        problems.append(Problem(e.path or str(p), f"{e.problem} (scene of {label})"))
        return None
    return replace(spec, path=p)


def with_frame(checked: SourceSpec | None, declared: SourceSpec, draft: Draft, label: str, frames: dict,
                problems: list[Problem]) -> SourceSpec | None:
    """The checked scene source with its frame resolved (:func:`r360gpu.io.frames.resolve_frame`):
    its own ``frame``, else scene.toml's top-level one, else "auto"."""
    if checked is None:
        return None
    from ..io.frames import find_dataparser_transforms, resolve_frame

    value = declared.frame if declared.frame is not None else draft.frame
    # "auto" depends on the scene's folder (the declared path: an INRIA folder, not its PLY)
    key = (value, str(find_dataparser_transforms(declared.path)) if value in (None, "auto") else None)
    if key not in frames:
        try:
            frames[key] = resolve_frame(value, scene=declared.path, cameras=draft.cameras_path, root=draft.root)
        except InputError as e:
            frames[key] = e
    frame = frames[key]
    if isinstance(frame, InputError):
        problems.append(Problem(frame.path, f"{frame.problem} (frame of {label})"))
        return None
    return replace(checked, frame=frame)


def _starts_with(p: Path, prefixes: tuple[bytes, ...]) -> bool:
    try:
        with open(p, "rb") as f:
            return f.read(8).startswith(prefixes)
    except OSError as e:
        raise InputError(f"cannot read file: {e.strerror or e}", p) from None


def _check_splat(p: Path) -> None:
    size = p.stat().st_size
    if size == 0:
        raise InputError("empty .splat file (contains no Gaussians)", p)
    if size % _SPLAT_RECORD_BYTES:
        raise InputError(f"truncated .splat file: {size} bytes is not a multiple of the "
                         f"{_SPLAT_RECORD_BYTES}-byte record", p)


def _check_ply(p: Path) -> None:
    ply = read_ply_header(p)
    if not (is_inria_ply(ply) or is_compressed_ply(ply)):
        raise InputError("PLY file is not a Gaussian-splat scene (no 'vertex' element with x and rot_0, "
                         "and not a .compressed.ply)", p)
    if ply.element("vertex").count == 0:
        raise InputError("scene has no Gaussians (vertex count 0)", p)
    # The loaders' own header checks, so that `check OK` means the scene will load.
    if is_compressed_ply(ply):
        check_compressed_header(ply)
    else:
        check_inria_header(ply)
    if ply.format == "ascii" or any(el.has_lists for el in ply.elements):
        return
    with open(p, "rb") as f:
        head = f.read(1 << 20)
    end = head.find(b"end_header")
    offset = end + len(b"end_header")
    offset += 2 if head[offset:offset + 2] == b"\r\n" else 1
    expected = offset + sum(el.count * el.dtype().itemsize for el in ply.elements)
    size = p.stat().st_size
    if size < expected:
        raise InputError(f"truncated PLY file: {size} bytes, the header declares {expected}", p)
    if size > expected:
        raise InputError(f"PLY file has {size - expected} bytes more than the header declares", p)


def check_renders(spec: SourceSpec, label: str, views: list[str], sizes: dict[str, tuple[int, int]], *,
                   depth_required: bool, where: str, problems: list[Problem], deep: bool = False,
                   sized_by: str = "the mask of view") -> None:
    """Append a problem for every evaluation view whose RGB (or, when the source has or needs one,
    depth) file is missing, unreadable or of another size than the view's mask (``sizes``; ``sized_by``
    names what gives the size, in the message)."""
    rgb_ok = spec.rgb_dir is not None and spec.rgb_dir.is_dir()
    if not rgb_ok:
        folder = spec.rgb_dir or spec.path
        broken = link_problem(folder)
        problems.append(Problem(str(folder), f"RGB folder of {label} is a {broken}" if broken
                                else f"RGB folder of {label} does not exist"))
    depth_dir = spec.depth_dir
    if depth_dir is None:
        if depth_required:
            problems.append(Problem(where, f"{label} has no depth: the geometric axis needs depth renderings "
                                           f"for pre and every method (a depth/ folder, or depth = \"FOLDER\")"))
    elif not depth_dir.is_dir():
        broken = link_problem(depth_dir)
        problems.append(Problem(str(depth_dir), f"depth folder of {label} is a {broken}" if broken
                                else f"depth folder of {label} does not exist"))
        depth_dir = None
    if not rgb_ok:
        return
    try:
        reader = RendersReader.from_dirs(spec.rgb_dir, depth_dir, spec.depth_scale)
    except InputError as e:
        problems.append(Problem(e.path, e.problem))
        return
    def decoded(header_size, read):  # deep: also decoded by the reader score uses (check OK = score reads it)
        return lambda path: (header_size(path), read(path))[0] if deep else header_size(path)

    kinds = [("RGB image", spec.rgb_dir, set(reader.views()), reader.rgb_path, decoded(image_size, read_rgb))]
    if reader.has_depth:
        kinds.append(("depth image", depth_dir, set(reader.depth_views()), reader.depth_path,
                      decoded(depth_size, lambda path: read_depth(path, reader.depth_scale))))
    for what, folder, available, lookup, size_of in kinds:
        missing = [v for v in views if v not in available]
        if missing:
            hint = reader.lossy_depth_hint(missing) if what == "depth image" else ""
            problems.append(Problem(str(folder), f"missing {what}s of {label} for {len(missing)} of {len(views)} "
                                                 f"views: {listed_names(missing)}{'; ' + hint if hint else ''}"))
        listed: list[Problem] = []
        for v in views:
            if v not in available:
                continue
            try:
                path = lookup(v)
                hw = size_of(path)
            except InputError as e:
                listed.append(Problem(e.path, e.problem))
                continue
            if v in sizes and tuple(hw) != sizes[v]:
                listed.append(Problem(str(path), f"{what} is {hw[1]}x{hw[0]}, {sized_by} {v!r} is "
                                                 f"{sizes[v][1]}x{sizes[v][0]} ({label})"))
        add_capped(problems, listed, str(folder), f"{what}s")


def check_orbit_renders(spec: SourceSpec, label: str, problems: list[Problem], *, deep: bool = False) -> None:
    """Append a problem for an orbit renders folder (``spec.orbit`` of a renders source) without a
    readable :data:`~.model.ORBIT_CAMERAS`, or without an RGB (and, when the source has depth, a
    depth) image of that file's size for every pose it lists.  Whether they are this run's poses is
    known only once the orbit is placed (`orbit_pose_problems`)."""
    orbit = spec.orbit
    try:
        cams = load_cameras_json(Path(orbit.path) / ORBIT_CAMERAS)
    except InputError as e:
        problems.append(Problem(e.path, f"{e.problem} ({label} orbit: the folder holds the {ORBIT_CAMERAS} "
                                        f"its renderings were made at, as score --orbit wrote it)"))
        return
    check_renders(orbit, f"{label} orbit", [c.name for c in cams], {c.name: (c.height, c.width) for c in cams},
                  depth_required=orbit.depth_dir is not None, where=str(orbit.path), problems=problems,
                  deep=deep, sized_by="the orbit camera")


#: Orbit renderings are this run's poses when every camera value agrees to this (relative to the
#: pose's distance from the world's origin for the centre); cameras.json holds them to float64.
ORBIT_POSE_TOLERANCE = 1e-6


def orbit_pose_problems(spec: SourceSpec, poses: list) -> list[str]:
    """What keeps the orbit renderings of ``spec`` (a renders source's `SourceSpec.orbit`) from
    being scored at ``poses`` (the orbit's kept cameras): poses missing from the folder's
    cameras.json, or there with another position, rotation, intrinsics or size ([]: none)."""
    given = {c.name: c for c in load_cameras_json(Path(spec.path) / ORBIT_CAMERAS)}
    missing, moved = [], []
    for cam in poses:
        c = given.get(cam.name)
        if c is None:
            missing.append(cam.name)
            continue
        tol = ORBIT_POSE_TOLERANCE
        if (c.width, c.height) != (cam.width, cam.height):
            moved.append(f"{cam.name} is {c.width}x{c.height} there, {cam.width}x{cam.height} here")
        elif (np.linalg.norm(c.center - cam.center) > tol * max(1.0, float(np.linalg.norm(cam.center)))
              or np.abs(c.R - cam.R).max() > tol
              or not np.allclose((c.fx, c.fy, c.cx, c.cy), (cam.fx, cam.fy, cam.cx, cam.cy), rtol=tol, atol=0)):
            moved.append(f"{cam.name} is another camera there")
    out = []
    if missing:
        out.append(f"{len(missing)} of this run's {len(poses)} orbit poses have no camera there: "
                   f"{listed_names(missing)}")
    if moved:
        out.append(f"{len(moved)} of them differ: " + ", ".join(moved[:3]) + (" ..." if len(moved) > 3 else ""))
    return out
