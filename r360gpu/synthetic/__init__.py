"""Built-in synthetic benchmark: procedural 3DGS scenes with simulated removal methods.

Each scene is a complete world of flat, textured 3D Gaussians (metres, z up)
with one target object; from it come the original reconstruction (pre), the
reference (the world without the target, including the background the target
hid), target masks rendered per view, and simulated removal methods with
known failure modes (:mod:`.methods`): ``clean``, ``floaters``,
``recoloured``, ``hole`` and ``over_removal`` (the default set), and
``backside`` (by name: a residue only an orbit can see).  Everything is written as
scene bundles (:mod:`.bundle`) that ``r360gpu score`` reads like real data.

Scenes (:data:`SCENES`): ``room`` (a living room, prompt "sofa") and
``garden`` (a walled patio on a lawn, prompt "bench"), the default set; and
``garden_open`` (by name: the garden without the wall behind the bench, so
an orbit sees the bench's far side).

Public API::

    generate_benchmark(out_dir, *, seed=0, n_views=20, width=480, height=360,
                       scenes=("room", "garden"), detail=1.0, methods=None,
                       camera_format="colmap", ctx=None, progress=False) -> list[Path]
    make_scene(name, *, seed=0, n_views=20, width=480, height=360, detail=1.0) -> SyntheticScene
    make_room(rng, ...), make_garden(rng, ...), make_garden_open(rng, ...)   one function per scene
    make_method(scene, method, *, seed=0) -> Gaussians
    clean / floaters / recoloured / hole / over_removal (scene, rng) -> Gaussians
    target_masks(scene, *, ctx=None) -> {view: (H, W) bool}
    write_bundle(scene, folder, *, seed=0, methods=None, camera_format="colmap", ctx=None) -> Path
    layouts.write_layouts(bundle, out, *, layouts=LAYOUTS, ctx=None)   a bundle as INRIA / gsplat /
                                                                        nerfstudio / public folders

Determinism: the same arguments give byte-identical files on the same
machine (all randomness comes from generators seeded by the seed and the
scene / method names).
"""
from __future__ import annotations

from .bundle import CAMERA_FORMATS, SCENES, generate_benchmark, make_method, make_scene, write_bundle
from .cameras import Rig, orbit_cameras, view_kinds
from .garden import make_garden, make_garden_open
from .masks import target_masks
from .methods import DEFAULT_METHODS, METHODS, backside, clean, floaters, hole, over_removal, recoloured
from .room import make_room
from .scene import SyntheticScene, hidden_background

__all__ = [
    "CAMERA_FORMATS", "DEFAULT_METHODS", "METHODS", "backside", "SCENES", "Rig", "SyntheticScene",
    "generate_benchmark", "make_scene", "make_method", "write_bundle",
    "make_room", "make_garden", "make_garden_open", "clean", "floaters", "recoloured", "hole", "over_removal",
    "target_masks", "hidden_background", "orbit_cameras", "view_kinds",
]
