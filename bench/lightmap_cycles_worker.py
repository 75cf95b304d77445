"""Blender Cycles' side of bench_lightmap_cycles.py, run by the bench under a Python that has
``bpy`` (Blender as a module, PyPI ``bpy``; not a dependency of shprobe):

    BPY_PYTHON bench/lightmap_cycles_worker.py JOB.json

JOB: {"glb", "width", "height", "samples": [...], "bounces", "threads", "out"}. The lightmap
.glb (shprobe's bake, so TEXCOORD_1 is shprobe's atlas) is imported; every material becomes a
Diffuse BSDF of its base-colour texture (TEXCOORD_0; no normal map, no specular: plain diffuse
lighting), the world a constant white sky of radiance 1, and the DIFFUSE pass (direct +
indirect, no colour: E / π) is baked into one float image on TEXCOORD_1 at each sample count.
Writes OUT/cycles_<samples>.npy (H, W, 3, rows in glTF order: row 0 at v = 0) and
OUT/cycles.json (seconds per bake).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import bpy
import numpy as np


def _diffuse_materials(uv0: str) -> None:
    for mat in bpy.data.materials:
        if not mat.use_nodes:
            continue
        nt = mat.node_tree
        base = None
        for node in nt.nodes:
            if node.type == "BSDF_PRINCIPLED":
                links = node.inputs["Base Color"].links
                if links and links[0].from_node.type == "TEX_IMAGE":
                    base = links[0].from_node.image
        for node in list(nt.nodes):
            nt.nodes.remove(node)
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
        if base is not None:
            tex = nt.nodes.new("ShaderNodeTexImage")
            tex.image = base
            uv = nt.nodes.new("ShaderNodeUVMap")
            uv.uv_map = uv0
            nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
            nt.links.new(tex.outputs["Color"], bsdf.inputs["Color"])


def main() -> None:
    job = json.loads(Path(sys.argv[1]).read_text())
    out = Path(job["out"])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=job["glb"])
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.render.threads_mode = "FIXED"
    scene.render.threads = int(job["threads"])
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.max_bounces = scene.cycles.diffuse_bounces = int(job["bounces"])
    scene.cycles.glossy_bounces = scene.cycles.transmission_bounces = 0
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world
    meshes = [o for o in scene.objects if o.type == "MESH"]
    uv0 = meshes[0].data.uv_layers[0].name
    _diffuse_materials(uv0)
    img = bpy.data.images.new("lightmap", job["width"], job["height"], float_buffer=True,
                              alpha=False)
    img.colorspace_settings.name = "Non-Color"
    for mat in bpy.data.materials:
        if mat.use_nodes:
            node = mat.node_tree.nodes.new("ShaderNodeTexImage")
            node.image = img
            mat.node_tree.nodes.active = node
            node.select = True
    bpy.ops.object.select_all(action="DESELECT")
    for o in meshes:
        o.data.uv_layers.active_index = 1  # TEXCOORD_1: shprobe's atlas
        o.select_set(True)
    bpy.context.view_layer.objects.active = meshes[0]
    seconds = {}
    for s in job["samples"]:
        scene.cycles.samples = int(s)
        t = time.perf_counter()
        bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT", "INDIRECT"}, margin=0,
                            use_clear=True, target="IMAGE_TEXTURES")
        seconds[str(s)] = time.perf_counter() - t
        px = np.empty(job["width"] * job["height"] * 4, np.float32)
        img.pixels.foreach_get(px)
        rgb = px.reshape(job["height"], job["width"], 4)[::-1, :, :3]  # Blender rows: bottom up
        np.save(out / f"cycles_{s}.npy", np.ascontiguousarray(rgb))
        print(f"cycles {s} samples: {seconds[str(s)]:.2f} s", flush=True)
    (out / "cycles.json").write_text(json.dumps(seconds))


if __name__ == "__main__":
    main()
