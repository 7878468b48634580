"""Interactive viewer of scene bundles: pre / reference / methods, overlays, metrics.

Start it with ``r360gpu view BUNDLE [--results results.json]`` or
``python -m viewer BUNDLE``.  Needs the ``viewer`` extra
(``pip install r360gpu[viewer]``: glfw, imgui-bundle, rendercanvas).

Modules: :mod:`.state` (key -> state machine), :mod:`.camera` (orbit / fly
controller), :mod:`.layers` (scenes as device images), :mod:`.overlays` and
:mod:`.compose` (GPU passes), :mod:`.live` (measurements at the current
viewpoint), :mod:`.target` (the target in 3D), :mod:`.quality`
(progressive resolution), :mod:`.results` and :mod:`.probe_masks` (what the
scores say), :mod:`.panels` (imgui), :mod:`.capture` (screenshots,
recordings), :mod:`.app` (the frame loop), :mod:`.launch` (command line).
"""
from __future__ import annotations
