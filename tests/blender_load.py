"""Run by Blender's Python (the ``bpy`` module), not by pytest: import glTF files as Blender would, report as JSON.

Usage: ``python blender_load.py REQUEST.json``. The request is ``{"out": REPORT.json, "files": [{"path": FILE,
"fps": N, "frames": [FRAME, ...]}, ...]}``; the report written to ``out`` is one entry per file (the importer
logs on stdout, so the report goes to a file).

For each file the scene is reset to Blender's factory settings with no objects, its frame rate set to ``fps``
(an integer; fps_base 1), and the file imported with ``bpy.ops.import_scene.gltf`` and its default options.
The importer keys an animation at ``time × fps`` frames, so with the file's own frame rate frame f of the
performance is Blender's frame f (the first at frame 0). Everything is in Blender's axes: the importer turns
glTF's y-up (x, y, z) into Blender's z-up (x, -z, y). Each entry holds:

- ``meshes``: per mesh object, its name, vertex count, shape-key names in order (``Basis`` first), the key each
  is relative to, whether the keys are relative, and each key's slider range (its value is clipped to it);
- ``actions``: per action, its name, frame range and F-curves (data path, array index, keyframe frames, values,
  interpolations), read from the layered action's channel bags;
- ``scene``: the scene's frame rate and frame range;
- ``samples``: per requested frame (a float: ``scene.frame_set`` with a subframe), the shape-key values of each
  mesh, each object's world matrix (4 × 4, rows), and the world-space vertex positions of each mesh as
  evaluated by the depsgraph (shape keys and parents applied).
"""

import json
import math
import sys

import bpy


def fcurves(action):
    for layer in action.layers:
        for strip in layer.strips:
            for bag in strip.channelbags:
                yield bag.slot.identifier if bag.slot else None, bag.fcurves


def report_action(action):
    curves = []
    for slot, bag in fcurves(action):
        for fc in bag:
            points = fc.keyframe_points
            curves.append({
                "slot": slot, "data_path": fc.data_path, "index": fc.array_index,
                "frames": [p.co[0] for p in points], "values": [p.co[1] for p in points],
                "interpolations": sorted({p.interpolation for p in points}),
            })
    return {"name": action.name, "frame_range": list(action.frame_range), "fcurves": curves}


def report_mesh(obj):
    keys = obj.data.shape_keys
    blocks = keys.key_blocks if keys else []
    return {
        "name": obj.name, "vertices": len(obj.data.vertices),
        "shape_keys": [k.name for k in blocks], "relative_to": [k.relative_key.name for k in blocks],
        "use_relative": bool(keys.use_relative) if keys else None,
        "slider_ranges": [[k.slider_min, k.slider_max] for k in blocks],
    }


def sample(scene, frame):
    whole = math.floor(frame)
    scene.frame_set(whole, subframe=frame - whole)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = {"frame": frame, "shape_keys": {}, "matrix_world": {}, "positions": {}}
    for obj in scene.objects:
        out["matrix_world"][obj.name] = [list(row) for row in obj.matrix_world]
        if obj.type != "MESH":
            continue
        keys = obj.data.shape_keys
        out["shape_keys"][obj.name] = {k.name: k.value for k in keys.key_blocks} if keys else {}
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        world = evaluated.matrix_world
        out["positions"][obj.name] = [list(world @ v.co) for v in mesh.vertices]
        evaluated.to_mesh_clear()
    return out


def load(path, fps, frames):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if fps != int(fps) or fps < 1:
        raise ValueError(f"fps must be a positive integer here, got {fps}")
    scene.render.fps, scene.render.fps_base = int(fps), 1.0
    result = bpy.ops.import_scene.gltf(filepath=path)
    if result != {"FINISHED"}:
        raise RuntimeError(f"the glTF importer did not finish on {path}: {result}")
    return {
        "path": path,
        "blender": bpy.app.version_string,
        "scene": {"fps": scene.render.fps / scene.render.fps_base,
                  "frame_range": [scene.frame_start, scene.frame_end]},
        "meshes": [report_mesh(o) for o in scene.objects if o.type == "MESH"],
        "objects": {o.name: {"type": o.type, "parent": o.parent.name if o.parent else None} for o in scene.objects},
        "actions": [report_action(a) for a in bpy.data.actions],
        "samples": [sample(scene, float(f)) for f in frames],
    }


def main(request_path):
    with open(request_path) as fh:
        request = json.load(fh)
    report = [load(f["path"], f["fps"], f.get("frames", [])) for f in request["files"]]
    with open(request["out"], "w") as fh:
        json.dump(report, fh)


if __name__ == "__main__":
    main(sys.argv[1])
