"""Which morph targets make each key-model of a glTF / VRM character: the binds shared by reader and writer.

A key-model is a weighted sum of morph targets, ``(mesh, target, factor)`` triples:

- a morph target name (``extras.targetNames`` of the mesh, else of its first primitive, else ``target_<i>``)
  binds every mesh that has a target of that name, factor 1: a head, its teeth, eyes and lashes that share
  ``jawOpen`` move together. Perfect Sync avatars (ARKit-named morph targets) are read this way;
- a VRM expression binds its ``morphTargetBinds`` (VRM 1.0 ``VRMC_vrm.expressions``, preset and custom) or its
  ``binds`` (VRM 0.x ``VRM.blendShapeMaster``, weights 0..100 scaled to 0..1). VRM 0.x presets take their
  VRM 1.0 names (:data:`VRM0_PRESETS`: ``joy`` is ``happy``, ``a`` is ``aa``, ...). A morph target name wins
  over an expression of the same name.

With key-model weights w_k, mesh m's target j gets Σ_k w_k · factor, which is the paper's Eq. 14 on the
key-models read as neutral + Σ factor · delta.
"""

from __future__ import annotations

__all__ = ["Bind", "morph_names", "keymodel_binds", "VRM0_PRESETS"]

Bind = tuple[int, int, float]

#: VRM 0.x preset names -> VRM 1.0 expression names.
VRM0_PRESETS = {"a": "aa", "i": "ih", "u": "ou", "e": "ee", "o": "oh", "joy": "happy", "angry": "angry",
                "sorrow": "sad", "fun": "relaxed", "blink": "blink", "blink_l": "blinkLeft",
                "blink_r": "blinkRight", "lookup": "lookUp", "lookdown": "lookDown", "lookleft": "lookLeft",
                "lookright": "lookRight", "neutral": "neutral"}


def morph_names(doc: dict, mesh: int) -> list[str]:
    """Morph target names of mesh ``mesh`` (empty when it has no targets)."""
    m = doc["meshes"][mesh]
    prims = m.get("primitives") or []
    n = len(prims[0].get("targets") or []) if prims else 0
    for extras in [m.get("extras")] + [p.get("extras") for p in prims[:1]]:
        names = extras.get("targetNames") if isinstance(extras, dict) else None
        if isinstance(names, list) and len(names) == n:
            return [str(x) for x in names]
    return [f"target_{i}" for i in range(n)]


def keymodel_binds(doc: dict) -> dict[str, list[Bind]]:
    """Every key-model name of the asset -> its binds (see the module notes), names in first-seen order."""
    out: dict[str, list[Bind]] = {}
    for m in range(len(doc.get("meshes") or [])):
        for j, name in enumerate(morph_names(doc, m)):
            out.setdefault(name, []).append((m, j, 1.0))
    for name, binds in _vrm_expressions(doc).items():
        if name not in out and binds:
            out[name] = binds
    return out


def _vrm_expressions(doc: dict) -> dict[str, list[Bind]]:
    ext = doc.get("extensions") or {}
    nodes, meshes = doc.get("nodes") or [], doc.get("meshes") or []
    out: dict[str, list[Bind]] = {}

    def ok(mesh, index) -> bool:
        return isinstance(mesh, int) and 0 <= mesh < len(meshes) and isinstance(index, int) \
            and 0 <= index < len(morph_names(doc, mesh))

    vrm1 = (ext.get("VRMC_vrm") or {}).get("expressions") or {}
    for group in ("preset", "custom"):
        for name, expr in (vrm1.get(group) or {}).items():
            binds = []
            for b in (expr or {}).get("morphTargetBinds") or []:
                node = b.get("node")
                mesh = nodes[node].get("mesh") if isinstance(node, int) and 0 <= node < len(nodes) else None
                if ok(mesh, b.get("index")):
                    binds.append((mesh, b["index"], float(b.get("weight", 1.0))))
            out[str(name)] = binds
    for group in ((ext.get("VRM") or {}).get("blendShapeMaster") or {}).get("blendShapeGroups") or []:
        preset = str(group.get("presetName") or "unknown").lower()
        name = VRM0_PRESETS.get(preset) or str(group.get("name") or preset)
        binds = [(b["mesh"], b["index"], float(b.get("weight", 100.0)) / 100.0)
                 for b in group.get("binds") or [] if ok(b.get("mesh"), b.get("index"))]
        out.setdefault(name, binds)
    return out
