"""What a scene bundle is once loaded: :class:`Bundle` and its parts, :class:`Problem`, :class:`BundleError`.

A bundle gathers everything r360gpu needs to score the methods of one scene:
the evaluation views (cameras and/or renderings), the target mask of each
view, the category prompt, the original reconstruction ("pre"), an optional
reference reconstruction of the physical post-removal capture, and one
source per evaluated method.  :mod:`.load` builds it from a folder.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..errors import InputError
from ..io.camera import Camera
from ..io.renders import RendersReader
from ..util.filehash import content_digest

from .names import RESERVED_METHOD_NAMES  # noqa: F401 (re-exported: defined where names are checked)
SOURCE_KINDS = ("scene", "renders")
#: The file an orbit renders folder holds the poses of its renderings in (the INRIA cameras.json
#: ``score --orbit`` writes for the kept poses).
ORBIT_CAMERAS = "cameras.json"
DEPTH_MODES = ("expected", "median")
LAYOUTS = ("scene.toml", "remove360", "group", "objects")


#: Per-source keys naming how r360gpu renders a splat scene (the conventions of
#: :class:`r360gpu.render.conventions.RenderOptions`; an absent key keeps r360gpu's default).
RENDER_KEYS = ("antialiased", "near", "no_coverage_alpha", "principal_point")
PRINCIPAL_POINTS = ("camera", "centre")  # checked against r360gpu.render.conventions by the tests


@dataclass(frozen=True)
class RenderSettings:
    """Render conventions set for one splat-scene source; None: r360gpu's default.

    antialiased: the source was trained with antialiasing (gsplat
    ``rasterize_mode="antialiased"``, INRIA ``antialiasing=True``,
    Mip-Splatting).  near: near plane (INRIA 0.2, gsplat 0.01).
    no_coverage_alpha: depth is 0 where alpha is below it (0: keep every
    depth, as gsplat).  principal_point: "camera" or "centre" (INRIA's
    original renderer ignores cx, cy).
    """

    antialiased: bool | None = None
    near: float | None = None
    no_coverage_alpha: float | None = None
    principal_point: str | None = None

    def given(self) -> dict:
        """The settings that were set, by key."""
        return {k: getattr(self, k) for k in RENDER_KEYS if getattr(self, k) is not None}


@dataclass(frozen=True)
class SourceSpec:
    """Where one reconstruction's views come from.

    kind "scene": ``path`` is the Gaussian-splat file (an INRIA output folder
    is resolved to its latest ``point_cloud.ply`` when the bundle is loaded),
    rendered by r360gpu at the bundle's cameras.
    kind "renders": ``path`` is the renders folder; ``rgb_dir`` holds
    ``<view>.png|jpg`` and ``depth_dir`` (None: no depth) ``<view>.png|exr|npy|tiff``,
    depth values multiplied by ``depth_scale`` (see :mod:`r360gpu.io.renders`).
    render: how a scene source is rendered (:class:`RenderSettings`).
    frame: the world frame of a scene's Gaussians (:class:`r360gpu.io.frames.Frame`;
    None: the cameras' frame); while a bundle is drafted, the ``frame`` value of scene.toml.
    orbit: for a renders method or reference, its renderings at the poses of ``score --orbit``, a
    renders source of its own whose ``path`` holds :data:`ORBIT_CAMERAS` (the poses they were made
    at, as r360gpu wrote them; docs/3d-evaluation.md); None: not rendered there.
    """

    kind: str
    path: Path
    depth_scale: float = 1.0
    rgb_dir: Path | None = None
    depth_dir: Path | None = None
    render: RenderSettings = RenderSettings()
    frame: object = None
    orbit: "SourceSpec | None" = None

    def reader(self) -> RendersReader:
        """A :class:`RendersReader` for a renders source (ValueError for a scene source)."""
        if self.kind != "renders":
            raise ValueError(f"a {self.kind!r} source has no renders reader")
        return RendersReader(self)


@dataclass
class BundleOptions:
    """Per-bundle evaluation options.

    background: render background colour, RGB in [0, 1] (splat scenes only).
    depth: rendered depth of a splat scene, "expected" (sum w z / sum w) or
    "median" (z where the accumulated opacity reaches 0.5).
    reference_free: score s_str = 1 - sim(I_pre, I_post) even when a
    reference exists.
    """

    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    depth: str = "expected"
    reference_free: bool = False


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a bundle: the file it concerns (None: the bundle as a whole) and what."""

    path: str | None
    message: str

    def __str__(self) -> str:
        return f"{self.path}: {self.message}" if self.path else self.message


#: Beyond this many problems of one kind in one folder, the rest is summarised in one line.
MAX_LISTED = 10


def listed_names(names: list[str]) -> str:
    """The first :data:`MAX_LISTED` names, quoted, and how many more (for a problem's message)."""
    listed = ", ".join(repr(v) for v in names[:MAX_LISTED])
    return listed + (f" and {len(names) - MAX_LISTED} more" if len(names) > MAX_LISTED else "")


def add_capped(problems: list[Problem], listed: list[Problem], folder: str, what: str) -> None:
    """Append the first :data:`MAX_LISTED` of ``listed`` to ``problems``, the rest as one line."""
    problems.extend(listed[:MAX_LISTED])
    if len(listed) > MAX_LISTED:
        problems.append(Problem(folder, f"... and {len(listed) - MAX_LISTED} more {what} with problems"))


class BundleError(InputError):
    """A bundle that cannot be used; ``problems`` lists every problem found, the message one per line."""

    def __init__(self, root: str | os.PathLike, problems: list[Problem]):
        self.problems = list(problems)
        n = len(self.problems)
        lines = [f"invalid bundle {os.fspath(root)} ({n} problem{'s' if n != 1 else ''}):"]
        lines += [f"  {p}" for p in self.problems]
        super().__init__("\n".join(lines))
        self.path = os.fspath(root)


@dataclass
class Bundle:
    """A loaded, validated scene bundle.

    views: evaluation view names, sorted.  cameras: the Camera of each
    evaluation view (None for renders-only bundles without cameras).  masks: the target-mask
    PNG of each view.  methods: in the order of the bundle file.
    layout: "scene.toml", "remove360" (a public Remove360 evaluation
    folder), "group" (several methods' folders, `.group`) or "objects"; config: the scene.toml (None for the Remove360 layout);
    cameras_path: what ``cameras`` named (None without cameras).
    method_pres: the methods that bring their own pre-removal source (the
    others use ``pre``); used for that method's IoU_pre / IoU_drop, D_pre and
    the reference-free structural comparison.
    """

    root: Path
    name: str
    prompt: str
    views: list[str]
    cameras: dict[str, Camera] | None
    masks: dict[str, Path]
    pre: SourceSpec
    reference: SourceSpec | None
    methods: dict[str, SourceSpec]
    options: BundleOptions = field(default_factory=BundleOptions)
    layout: str = "scene.toml"
    config: Path | None = None
    cameras_path: Path | None = None
    #: [expected.METHOD] of scene.toml: {method: {"failure", "caught_by"}} (r360gpu.bundle.expected)
    expected: dict = field(default_factory=dict)
    method_pres: dict[str, SourceSpec] = field(default_factory=dict)
    #: [target] of scene.toml (r360gpu.bundle.target.TargetSpec): views without a given mask get one rendered
    target: object = None
    #: the ``--views`` patterns ``views`` were selected by (None: none given), so a selection is made once
    #: (:func:`r360gpu.bundle.views.narrow_views`)
    view_patterns: tuple | None = None

    def sources(self) -> dict[str, SourceSpec]:
        """Every source by name: "pre", "reference" (when present), the methods, then each
        method's own pre as ``"pre/<method>"`` (see `pre_name`)."""
        out = {"pre": self.pre}
        if self.reference is not None:
            out["reference"] = self.reference
        out.update(self.methods)
        out.update({pre_name(m): s for m, s in self.method_pres.items()})
        return out

    def with_render_settings(self, **settings) -> "Bundle":
        """A copy whose splat-scene sources use ``settings`` (keys of `RENDER_KEYS`;
        None leaves a source's own value), e.g. ``antialiased=True`` from ``score --antialiased``."""
        from dataclasses import replace

        settings = {k: v for k, v in settings.items() if v is not None}
        unknown = set(settings) - set(RENDER_KEYS)
        if unknown:
            raise ValueError(f"unknown render settings {sorted(unknown)}")
        if not settings:
            return self

        from ..io.gaussians import Gaussians

        def apply(s):
            if isinstance(s, Gaussians):
                raise InputError(f"scene {self.name!r}: render settings {settings} cannot be set on Gaussians in "
                                 "memory; pass r360gpu.render.sources.SceneSource(gaussians, render={...}) instead")
            if not isinstance(s, SourceSpec) or s.kind != "scene":
                return s  # renders and device views are images already
            return replace(s, render=replace(s.render, **settings))

        return replace(self, pre=apply(self.pre), reference=apply(self.reference),
                       methods={m: apply(s) for m, s in self.methods.items()},
                       method_pres={m: apply(s) for m, s in self.method_pres.items()})

    def pre_of(self, method: str) -> SourceSpec:
        """The pre-removal source ``method`` is scored against."""
        return self.method_pres.get(method, self.pre)

    def fingerprint(self) -> str:
        """A hex SHA-256 that changes when anything the scores depend on may have changed.

        Hashed: the resolved settings (name, prompt, views, sources, options,
        layout), the bytes of scene.toml, and the path and content digest of
        every file the bundle reads: camera files, the masks and renderings of
        the evaluation views, the splat files.  Digests are remembered per
        file identity and ctime once a file is 2 s old
        (`r360gpu.util.filehash`), so an unchanged rerun reads nothing,
        while other bytes of the same size with a restored mtime still change
        the fingerprint.  A missing file is hashed as missing.  Paths are taken
        relative to the bundle root when inside it.
        """
        return self.fingerprint_of(self.file_digests())

    def file_digests(self) -> dict[str, str | None]:
        """{path: content digest, None when missing} of every file the bundle reads
        (`fingerprint`); a run keeps them to check that what it decoded is what it keyed."""
        files = [os.fspath(f) for f in self._referenced_files()]

        def one(f: str) -> str | None:
            try:
                return content_digest(f, Path(f).stat())
            except OSError:
                return None

        if len(files) < 8:
            return {f: one(f) for f in files}
        # on every core: reading and hashing release the GIL (a first run hashes every rendering)
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(min(8, os.cpu_count() or 1), thread_name_prefix="r360-hash") as pool:
            return dict(zip(files, pool.map(one, files)))

    def file_digests_paths(self) -> list[str]:
        """The paths `file_digests` hashes, without hashing them."""
        return [os.fspath(f) for f in self._referenced_files()]

    def fingerprint_of(self, digests: dict[str, str | None]) -> str:
        """`fingerprint` from digests taken before (`file_digests`)."""
        h = hashlib.sha256()

        def add(*item) -> None:
            h.update(json.dumps(item, sort_keys=True, default=str).encode())
            h.update(b"\n")

        settings = {
            "name": self.name, "prompt": self.prompt, "views": self.views, "layout": self.layout,
            "options": asdict(self.options),
            "sources": {k: self._source_settings(s) for k, s in self.sources().items()},
            "cameras": self._rel(self.cameras_path) if self.cameras_path else None,
        }
        add("settings", settings)
        if self.config is not None:
            try:
                add("config", hashlib.sha256(self.config.read_bytes()).hexdigest())
            except OSError:
                add("config", None)
        for path, digest in digests.items():
            add("file", self._rel(Path(path)), digest)
        return h.hexdigest()

    def view_files(self, view: str, readers: dict | None = None) -> list[str]:
        """The paths (as keyed by `file_digests`) of the files the scores of ``view`` are decoded from: its mask, the
        renderings of every renders source and every splat file (a subset of `file_digests`)."""
        files = [self.masks[view]] if isinstance(self.masks.get(view), (str, os.PathLike)) else []
        readers = {} if readers is None else readers  # {source name: RendersReader}, kept by the caller
        for name, spec in self.sources().items():
            if not isinstance(spec, SourceSpec):
                continue
            if spec.kind == "scene":
                files.append(spec.path)
                continue
            try:
                reader = readers.get(name) or readers.setdefault(name, spec.reader())
                files.append(reader.rgb_path(view))
                if reader.has_depth:
                    files.append(reader.depth_path(view))
            except InputError:
                continue
        return [os.fspath(f) for f in files]

    def _rel(self, p: Path) -> str:
        try:
            return Path(p).relative_to(self.root).as_posix()
        except ValueError:
            return Path(p).as_posix()

    def _source_settings(self, s: SourceSpec) -> dict:
        return {"kind": s.kind, "path": self._rel(s.path), "depth_scale": s.depth_scale,
                "rgb_dir": s.rgb_dir and self._rel(s.rgb_dir), "depth_dir": s.depth_dir and self._rel(s.depth_dir),
                "render": s.render.given(),
                # the frame's matrix (its origin names absolute paths: a moved bundle keeps its cache)
                **({"frame": s.frame.matrix} if hasattr(s.frame, "matrix") else {})}

    def _referenced_files(self) -> list[Path]:
        files: list[Path] = []
        if self.cameras_path is not None:
            files += _camera_files(self.cameras_path)
        files += [self.masks[v] for v in self.views if v in self.masks]
        if self.target is not None and isinstance(getattr(self.target, "indices", None), Path):
            files.append(self.target.indices)
        for spec in self.sources().values():
            if spec.kind == "scene":
                files.append(spec.path)
                continue
            try:
                reader = spec.reader()
            except InputError:
                files.append(spec.rgb_dir or spec.path)  # hashed as missing
                continue
            for v in self.views:
                for lookup in (reader.rgb_path, reader.depth_path) if reader.has_depth else (reader.rgb_path,):
                    try:
                        files.append(lookup(v))
                    except InputError:
                        files.append(Path(spec.path) / f"<missing {v}>")
        return files


def pre_name(method: str) -> str:
    """The source name of ``method``'s own pre: ``"pre/<method>"``, which no method can take
    (method names name output folders, so they hold no path separator)."""
    return f"pre/{method}"


def _camera_files(path: Path) -> list[Path]:
    """The files a camera loader may read for ``path``: itself, or the plain files of the
    folder and of its sparse/ and sparse/0 sub-folders."""
    path = Path(path)
    if not path.is_dir():
        return [path]
    out = []
    for d in (path, path / "sparse", path / "sparse" / "0"):
        if d.is_dir():
            out += sorted(f for f in d.iterdir() if f.is_file())
    return out


@dataclass
class Draft:
    """A bundle as declared, before its files are checked (built by :mod:`.scene_toml` from
    scene.toml and by :mod:`.remove360_layout` from a public Remove360 folder).

    ``view_patterns`` None means "every view with a mask"; ``patterns_origin``
    names where explicit patterns came from (for messages).  Sources that
    could not be parsed are None (their problems are already reported).
    """

    root: Path
    layout: str
    config: Path | None = None
    name: str = ""
    prompt: str | None = None
    cameras_path: Path | None = None
    masks_dir: Path | None = None
    view_patterns: list[str] | None = None
    patterns_origin: str = "views"
    pre: SourceSpec | None = None
    reference: SourceSpec | None = None
    methods: dict[str, SourceSpec | None] = field(default_factory=dict)
    method_pres: dict[str, SourceSpec | None] = field(default_factory=dict)
    options: BundleOptions = field(default_factory=BundleOptions)
    expected: dict = field(default_factory=dict)
    frame: str | None = None  # scene.toml's top-level frame: the default of every scene source
    target: object = None
