"""The Mitsuba XML Cornell box (tools/crosscheck/scenes/cornell-box.xml) built
from scratch in Blender Cycles, rendered on the CPU and timed.

Run by bench/compare.py in a child process with the venv's Python (bpy is
heavy and keeps global state):

    python bench/cycles_cornell.py --res 512 --spp 256 --repeat 3 --out cycles.exr

Prints one line of JSON: the seconds spent importing bpy and building the
scene, the wall time of each render (bpy.ops.render.render, which includes
Cycles' scene sync of these 18 quads; up to --repeat renders, fewer once
one takes longer than --repeat-under seconds), and the settings used. The image is written as a 32-bit float EXR in Blender's
scene-linear space (linear Rec.709, the space Mitsuba's `rgb` values and
its output are in), RGB without alpha.
"""
import argparse
import json
import math
import os
import sys
import time

_start = time.perf_counter()
import bpy  # noqa: E402  (timed: Blender's start-up)
import numpy as np  # noqa: E402

IMPORT_SECONDS = time.perf_counter() - _start

# Linear RGB reflectances and radiance from the XML.
WHITE = (0.885809, 0.698859, 0.666422)
GREEN = (0.105421, 0.37798, 0.076425)
RED = (0.570068, 0.0430135, 0.0443706)
LIGHT_RADIANCE = (18.387, 13.9873, 6.75357)

# Cycles' Gaussian filter of width w is exp(-x²/(2σ²)) with σ = w/4,
# truncated at ±1.5 w (film.cpp: the table spans 3 w and evaluates
# exp(-2 (6x / 3w)²)). Mitsuba's Gaussian has σ = 0.5 px, truncated at
# ±2 px, so w = 2 px gives the same kernel (Cycles keeps the tail from 2
# to 3 px, where the Gaussian is below 3e-4 of its peak).
FILTER_WIDTH = 2.0

# Mitsuba's max_depth 8 allows paths of 8 segments from the camera, so 7
# scattering vertices, the first lit directly and the other 6 indirect
# bounces. Cycles' max_bounces counts the indirect bounces only (0 renders
# direct lighting, like Mitsuba's max_depth 2), so the equivalent is 6. With 7
# the image is 1.0% brighter in red, 0.1% in green (one more bounce of light).
BOUNCES = 6


def scale(x, y, z):
    return np.diag([x, y, z, 1.0])


def translate(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def rotate_x(degrees):
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rotate_y(degrees):
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def chain(*steps):
    """Mitsuba's <transform>: the steps apply in the order written."""
    m = np.eye(4)
    for step in steps:
        m = step @ m
    return m


# Mitsuba's rectangle: [-1, 1]² in the xy plane, front face +z
# (counter-clockwise seen from +z).
RECTANGLE = ([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2, 3)])
# Mitsuba's cube: [-1, 1]³, faces wound counter-clockwise seen from outside.
CUBE = (
    [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)],
    [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)],
)


def mesh_object(name, shape, transform, material):
    verts, faces = shape
    v = np.c_[np.array(verts, float), np.ones(len(verts))] @ transform.T
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in v[:, :3]], [], faces)
    mesh.update()
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def diffuse_material(name, rgb):
    mat = bpy.data.materials.new(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0  # Lambert
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def light_material():
    """Mitsuba's area emitter on a white diffuse rectangle: the front face
    emits LIGHT_RADIANCE (a Cycles emission of strength 1 emits its colour
    as radiance) and reflects like the white walls; the back face neither
    emits nor reflects (Mitsuba's emitter and diffuse BSDF are one-sided)."""
    mat = bpy.data.materials.new("light")
    mat.cycles.emission_sampling = "FRONT"  # light sampling picks the front face only
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (*LIGHT_RADIANCE, 1.0)
    emission.inputs["Strength"].default_value = 1.0
    white = nodes.new("ShaderNodeBsdfDiffuse")
    white.inputs["Color"].default_value = (*WHITE, 1.0)
    white.inputs["Roughness"].default_value = 0.0
    front = nodes.new("ShaderNodeAddShader")
    links.new(emission.outputs["Emission"], front.inputs[0])
    links.new(white.outputs["BSDF"], front.inputs[1])
    black = nodes.new("ShaderNodeBsdfDiffuse")
    black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    geometry = nodes.new("ShaderNodeNewGeometry")
    sides = nodes.new("ShaderNodeMixShader")
    links.new(geometry.outputs["Backfacing"], sides.inputs["Fac"])
    links.new(front.outputs["Shader"], sides.inputs[1])
    links.new(black.outputs["BSDF"], sides.inputs[2])
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(sides.outputs["Shader"], out.inputs["Surface"])
    return mat


def build_scene(res, spp, threads):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    white = diffuse_material("white", WHITE)
    green = diffuse_material("green", GREEN)
    red = diffuse_material("red", RED)
    mesh_object("light", RECTANGLE, chain(scale(0.23, 0.19, 0.19), rotate_x(90), translate(0, 0.99, 0.01)),
                light_material())
    mesh_object("floor", RECTANGLE, chain(rotate_x(-90), translate(0, -1, 0)), white)
    mesh_object("ceiling", RECTANGLE, chain(rotate_x(90), translate(0, 1, 0)), white)
    mesh_object("back", RECTANGLE, translate(0, 0, -1), white)
    mesh_object("green wall", RECTANGLE, chain(rotate_y(-90), translate(1, 0, 0)), green)
    mesh_object("red wall", RECTANGLE, chain(rotate_y(90), translate(-1, 0, 0)), red)
    mesh_object("short box", CUBE, chain(scale(0.3, 0.3, 0.3), rotate_y(-17), translate(0.335, -0.7, 0.38)), white)
    mesh_object("tall box", CUBE, chain(scale(0.3, 0.61, 0.3), rotate_y(18.25), translate(-0.33, -0.4, -0.28)), white)

    # Camera at (0, 0, 3.9) looking at the origin with +y up: a Blender camera
    # looks down its local -z with local +y up, so no rotation is needed.
    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "PERSP"
    cam_data.lens_unit = "FOV"
    # The XML's fov is on the smaller axis; the image is square, so that is
    # the horizontal one.
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.angle = math.radians(39.3077)
    cam_data.clip_start = 0.001
    cam_data.clip_end = 100.0
    camera = bpy.data.objects.new("camera", cam_data)
    camera.location = (0.0, 0.0, 3.9)
    camera.rotation_euler = (0.0, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera

    world = bpy.data.worlds.new("black")
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    background.inputs["Strength"].default_value = 0.0
    world.cycles.sampling_method = "NONE"  # nothing to sample in a black world
    scene.world = world

    render = scene.render
    render.engine = "CYCLES"
    render.resolution_x = res
    render.resolution_y = res
    render.resolution_percentage = 100
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.threads_mode = "FIXED"
    render.threads = threads
    render.use_persistent_data = False
    render.film_transparent = False
    render.image_settings.file_format = "OPEN_EXR"
    render.image_settings.color_depth = "32"
    render.image_settings.color_mode = "RGB"

    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = spp
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.seed = 0
    cycles.use_animated_seed = False
    cycles.max_bounces = BOUNCES
    cycles.diffuse_bounces = BOUNCES
    cycles.glossy_bounces = BOUNCES
    cycles.transmission_bounces = BOUNCES
    cycles.volume_bounces = 0  # no volumes in the scene
    cycles.transparent_max_bounces = BOUNCES
    cycles.min_light_bounces = 0
    cycles.sample_clamp_direct = 0.0  # 0: no clamping
    cycles.sample_clamp_indirect = 0.0
    cycles.blur_glossy = 0.0
    cycles.caustics_reflective = True
    cycles.caustics_refractive = True
    cycles.light_sampling_threshold = 0.0  # no lights skipped for low contribution
    cycles.pixel_filter_type = "GAUSSIAN"
    cycles.filter_width = FILTER_WIDTH

    view = scene.view_settings
    view.view_transform = "Standard"
    view.look = "None"
    view.exposure = 0.0
    view.gamma = 1.0
    return {
        "blender": bpy.app.version_string,
        "device": cycles.device,
        "threads": render.threads,
        "samples": cycles.samples,
        "sampling_pattern": cycles.sampling_pattern,
        "light_tree": cycles.use_light_tree,
        "max_bounces": cycles.max_bounces,
        "pixel_filter": f"{cycles.pixel_filter_type.lower()} {cycles.filter_width:g} px (σ = {cycles.filter_width / 4:g} px)",
        "view_transform": view.view_transform,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", type=int, default=512)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--repeat-under", type=float, default=180.0,
                    help="repeat only while one render takes less than this many seconds")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()

    start = time.perf_counter()
    settings = build_scene(args.res, args.spp, args.threads)
    setup = time.perf_counter() - start

    times = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        bpy.ops.render.render()
        times.append(time.perf_counter() - start)
        if times[-1] > args.repeat_under:
            break
    bpy.data.images["Render Result"].save_render(args.out)
    print(json.dumps({"import_s": IMPORT_SECONDS, "setup_s": setup, "render_s": times, "settings": settings}))


if __name__ == "__main__":
    sys.exit(main())
