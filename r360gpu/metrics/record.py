"""The per-view record: every measurement of one view of one (scene, method).

:class:`ViewRecord` keeps the view's name, scene and method, the probes used
(their ``describe()``: name, kind, model hashes, parameters), and all per-view
values: one :class:`~r360gpu.metrics.semantic.SemanticView` and one
:class:`~r360gpu.metrics.structural.StructuralView` per probe (keyed by probe
name, so several probes per axis fit), the geometric summary
(:meth:`~r360gpu.metrics.geometric.GeometricView.summary`, no images) and the
fidelity values.

``to_dict()`` gives strict JSON (``json.dumps(..., allow_nan=False)`` works;
non-finite floats such as an identical-image PSNR are tagged, see
:mod:`r360gpu.metrics.json_values`) and ``from_dict(to_dict())`` returns an equal
record: Python writes floats with ``repr``, which round-trips exactly.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from ..errors import InputError
from ..protocol import VIEW_RECORD_SCHEMA
from . import json_values
from .fidelity import FidelityView
from .geometric import GeometricView
from .semantic import SemanticView
from .structural import StructuralView

#: Format tag written into every record.
SCHEMA = VIEW_RECORD_SCHEMA


@dataclass(frozen=True)
class ViewRecord:
    """All measurements of one view.

    view: view name (image file stem); scene, method: names.
    probes: the ``describe()`` dict of every probe used (name, kind, models
        {file: sha256}, params).
    semantic: {probe name: SemanticView}.
    structural: {probe name: StructuralView}.
    geometric: GeometricView.summary() (acc_depth, threshold, ...), or None.
    fidelity: FidelityView (I_post vs I_ref), or None without a reference.
    """

    view: str
    scene: str
    method: str
    probes: tuple[dict, ...] = ()
    semantic: dict[str, SemanticView] = field(default_factory=dict)
    structural: dict[str, StructuralView] = field(default_factory=dict)
    geometric: dict | None = None
    fidelity: FidelityView | None = None

    @classmethod
    def build(
        cls,
        view: str,
        scene: str,
        method: str,
        *,
        probes: Iterable[dict] = (),
        semantic: Iterable[SemanticView] | Mapping[str, SemanticView] = (),
        structural: Iterable[StructuralView] | Mapping[str, StructuralView] = (),
        geometric: GeometricView | dict | None = None,
        fidelity: FidelityView | None = None,
    ) -> "ViewRecord":
        """Record from measurement objects; lists of views are keyed by their ``probe`` name."""
        geo = geometric.summary() if isinstance(geometric, GeometricView) else geometric
        return cls(
            view=str(view),
            scene=str(scene),
            method=str(method),
            probes=tuple(dict(p) for p in probes),
            semantic=_by_probe(semantic, "semantic"),
            structural=_by_probe(structural, "structural"),
            geometric=None if geo is None else dict(geo),
            fidelity=fidelity,
        )

    def to_dict(self) -> dict:
        return {
            "schema": SCHEMA,
            "view": self.view,
            "scene": self.scene,
            "method": self.method,
            "probes": json_values.enc_tree(list(self.probes)),
            "semantic": {k: v.to_dict() for k, v in self.semantic.items()},
            "structural": {k: v.to_dict() for k, v in self.structural.items()},
            "geometric": None if self.geometric is None else json_values.enc_tree(self.geometric),
            "fidelity": None if self.fidelity is None else self.fidelity.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict) -> "ViewRecord":
        what = "view record"
        schema = json_values.field(d, "schema", what)
        if schema != SCHEMA:
            raise InputError(f"{what}: unknown schema {schema!r} (expected {SCHEMA!r})")
        f = lambda k: json_values.field(d, k, what)  # noqa: E731
        geo = f("geometric")
        fid = f("fidelity")
        return cls(
            view=str(f("view")),
            scene=str(f("scene")),
            method=str(f("method")),
            probes=tuple(json_values.dec_tree(p) for p in f("probes")),
            semantic={str(k): SemanticView.from_dict(v) for k, v in f("semantic").items()},
            structural={str(k): StructuralView.from_dict(v) for k, v in f("structural").items()},
            geometric=None if geo is None else json_values.dec_tree(geo),
            fidelity=None if fid is None else FidelityView.from_dict(fid),
        )


def _by_probe(views, axis: str) -> dict:
    if isinstance(views, Mapping):
        return {str(k): v for k, v in views.items()}
    out: dict = {}
    for v in views:
        if v.probe in out:
            raise InputError(f"{axis}: two readings from probe {v.probe!r} for one view")
        out[v.probe] = v
    return out
