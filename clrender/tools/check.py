"""Device-portability check: render fixed small cases on several OpenCL devices and compare
every AOV against the first device.

Integer AOVs (triangle ids, lights per tile) must be identical; float AOVs must stay within
the tolerances below, which come from what can legitimately differ between conforming
implementations (library-function ulps in shading, last-bit differences after quantization).

    report = clrender.tools.check.run_check(devices="all")
    report.ok, report.rows, report.table()
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from clrender.abi import aovs as aov_table
from clrender.scene.camera import Camera
from clrender.scene.model import Scene

# AOV -> (kind, tolerance). "exact": bit-identical; "abs": |a-b| <= tol; "peak": |a-b| <= tol·max|a|;
# "peak_or_rel": |a-b| <= max(tol_peak·max|a|, tol_rel·|a|).
TOLERANCES = {
    "triangle_id": ("exact", 0.0),
    "object_id": ("exact", 0.0),       # from triangle_id through the scene's tables
    "material_id": ("exact", 0.0),
    "light_count": ("exact", 0.0),
    "depth": ("rel", 1e-6),           # same fixed-point raster: only depth/far·far rounding
    "normal": ("abs", 2e-3),          # 12-bit octahedral: a last-bit difference is ~1e-3
    "albedo": ("abs", 1e-2),          # 8-bit sRGB: one code near white
    "velocity": ("abs", 1e-3),
    # shading: rsqrt/powr ulps across implementations; a value may also differ by 1e-3 of itself,
    # which the glTF BRDF's GGX peak needs: its D = α²/(π q²) turns an ulp of N·H into ~1e-4 of a
    # sharp highlight (the ortho demo's torus: 1.6e-4 between PoCL and Oclgrind)
    "color": ("peak_or_rel", (1e-4, 1e-3)),
    "image": ("abs", 1.0),            # one 8-bit code after tone mapping
    # SSAO uses only +-*/ and sqrt: identical bits where they are correctly rounded (PoCL,
    # Oclgrind); elsewhere a sample may land one pixel over: <= 1/8 raw, <= 1/200 once blurred.
    "ao": ("abs", 1e-2),
    # Shadow maps are the same fixed-point raster; a depth compare within an ulp of the bias can
    # flip one filter tap (<= 1/9 of pcf3x3, 1/16 of poisson) where implementations round differently.
    "shadow": ("abs", 0.12),
    "fragment_count": ("exact", 0.0),  # the same fixed-point coverage and depth as the raster
    "transmittance": ("abs", 1e-5),    # products of the same alphas (texture sampling ulps)
    "edges": ("exact", 0.0),           # the edge mask: thresholds on the same G-buffer words
    "specular_intensity": ("abs", 1 / 255 + 1e-6),   # 8-bit unorm: one code
    "specular_power": ("rel", 0.031),  # log2 in 8 bits: one code is a factor 2^(11/255)
    "emissive": ("abs", 1e-2),         # 8-bit sRGB: one code near white
    "occlusion": ("abs", 1 / 255 + 1e-6),
    "base_color": ("abs", 1e-2),       # the glTF BRDF's material bits (clrender/abi/gbuffer.py): as albedo's
    "metallic": ("abs", 1 / 255 + 1e-6),
    "roughness": ("abs", 1 / 255 + 1e-6),
    "shading_model": ("exact", 0.0),
}

# With the LDR post effects a last-ulp difference in the HDR colour can flip FXAA's contrast test
# or edge AA's blend on a pixel: the post case's image allows 0.5 % of its values past one code,
# none past 16.
POST_TOLERANCES = {**TOLERANCES, "image": ("mostly", (1.0, 0.005, 16.0))}

# The case with every post effect on (docs/post.md): render options and the previous camera's
# offset from the current one (motion blur needs motion).
POST_OPTIONS = dict(ssao=True, supersample=2, supersample_filter="lanczos2", bloom=True, bloom_threshold=0.5,
                    motion_blur=True, edge_aa=True, color_aa="fxaa", hatching=True)

# The demo again under other options (besides "post"): the renderer variants (docs/variants.md).
VARIANT_OPTIONS = {
    "prepass": dict(pipeline="light_prepass", msaa=4, light_buffer_specular="luminance", ssao=True),
    "indexed": dict(pipeline="light_indexed"),
}

REPO_SCENES = Path(__file__).resolve().parents[2] / "scenes"

# Light-accumulation variants (docs/light_accumulation.md), each a case of its own: the soup (64
# lights, a shadowed spot and the sun) rendered with light_culling set to it.
LIGHT_VARIANTS = ("quads", "stencil")


@dataclass(frozen=True)
class CheckRow:
    device: str
    case: str
    aov: str
    max_abs: float
    max_rel: float
    over: int          # pixels (elements) outside the tolerance
    tolerance: str
    ok: bool


@dataclass(frozen=True)
class CheckReport:
    reference: str
    devices: tuple
    rows: tuple = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        return all(r.ok for r in self.rows)

    def table(self) -> str:
        head = f"{'device':<44} {'case':<8} {'aov':<12} {'max abs':>10} {'max rel':>10} {'over':>6}  tolerance     result"
        lines = [f"reference device: {self.reference}", head, "-" * len(head)]
        for r in self.rows:
            lines.append(f"{r.device[:44]:<44} {r.case:<8} {r.aov:<12} {r.max_abs:>10.3g} {r.max_rel:>10.3g} "
                         f"{r.over:>6}  {r.tolerance:<13} {'ok' if r.ok else 'MISMATCH'}")
        lines.append("all AOVs agree" if self.ok else "MISMATCH: see the rows above")
        return "\n".join(lines)

    def summary(self) -> str:
        """One row per AOV, one column per compared device: "=" where every case is bit-identical,
        else the largest difference over the cases (and "!" past the tolerance). The table in
        docs/devices.md is this one."""
        compared = [d for d in self.devices if d != self.reference]
        worst: dict = {}
        for r in self.rows:
            max_abs, bad = worst.get((r.aov, r.device), (0.0, False))
            worst[r.aov, r.device] = (max(max_abs, r.max_abs), bad or not r.ok)
        # "2:0 pocl 3.1+debian: pthread-..." -> "2:0 pocl 3.1+debian": the id and the implementation
        labels = [d.split(" ", 1)[0] + " " + d.split(" ", 1)[-1].split(":")[0][:24] for d in compared]
        width = max([12, *(len(x) for x in labels)])
        lines = [f"against {self.reference}", f"{'aov':<18}" + "".join(f"{x:>{width + 2}}" for x in labels)]
        for aov in dict.fromkeys(r.aov for r in self.rows):
            cells = []
            for d in compared:
                max_abs, bad = worst.get((aov, d), (0.0, False))
                cells.append(("=" if max_abs == 0 else f"{max_abs:.3g}") + (" !" if bad else ""))
            lines.append(f"{aov:<18}" + "".join(f"{c:>{width + 2}}" for c in cells))
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"reference": self.reference, "devices": list(self.devices), "ok": self.ok,
                "rows": [r.__dict__ for r in self.rows]}


def compare(aov: str, ref: np.ndarray, got: np.ndarray, tolerances: Optional[dict] = None
            ) -> tuple[float, float, int, str, bool]:
    """(max abs, max rel, elements over tolerance, tolerance text, ok) for one AOV."""
    kind, tol = (tolerances or TOLERANCES)[aov]
    if ref.shape != got.shape:
        return float("inf"), float("inf"), int(ref.size), f"shape {ref.shape}", False
    a, b = ref.astype(np.float64), got.astype(np.float64)
    both_inf = np.isinf(a) & np.isinf(b) & (np.sign(a) == np.sign(b))
    with np.errstate(invalid="ignore"):          # inf - inf where both are background
        diff = np.where(both_inf, 0.0, np.abs(a - b))
    diff = np.where(np.isnan(diff), np.inf, diff)
    scale = np.where(np.isfinite(a), np.maximum(np.abs(a), 1e-30), 1.0)   # inf vs finite: always over
    max_abs = float(diff.max()) if diff.size else 0.0
    max_rel = float((diff / scale).max()) if diff.size else 0.0
    if kind == "exact":
        over, text = int(np.count_nonzero(a != b)), "identical"
    elif kind == "rel":
        over, text = int(np.count_nonzero(diff > tol * scale)), f"rel {tol:g}"
    elif kind == "peak":
        peak = float(np.abs(a[np.isfinite(a)]).max()) if np.isfinite(a).any() else 0.0
        over, text = int(np.count_nonzero(diff > tol * peak)), f"{tol:g}·peak"
    elif kind == "peak_or_rel":                  # within tol·peak or rel·|value|
        tol_peak, tol_rel = tol
        peak = float(np.abs(a[np.isfinite(a)]).max()) if np.isfinite(a).any() else 0.0
        over = int(np.count_nonzero((diff > tol_peak * peak) & (diff > tol_rel * scale)))
        text = f"{tol_peak:g}·peak or rel {tol_rel:g}"
    elif kind == "mostly":                       # (abs tolerance, fraction allowed over it, hard limit)
        limit, frac, hard = tol
        over, text = int(np.count_nonzero(diff > limit)), f"abs {limit:g} ({frac:.1%}; <= {hard:g})"
        return max_abs, max_rel, over, text, over <= frac * diff.size and max_abs <= hard
    else:
        over, text = int(np.count_nonzero(diff > tol)), f"abs {tol:g}"
    return max_abs, max_rel, over, text, over == 0


def default_cases(width: int, height: int) -> list[tuple[str, Scene, Camera]]:
    """The fixed portability cases: the bundled demo (also through an orthographic camera: the
    ORTHO kernel variants), a random soup, a dense tile, many lights."""
    from clrender.loaders import load_scene
    cases = []
    demo = REPO_SCENES / "demo.toml"
    if demo.is_file():
        scene = load_scene(demo)
        cases.append(("demo", scene, scene.camera))
        c = scene.camera       # the orthographic view as tall as the perspective one at its target
        half = float(np.linalg.norm(np.subtract(c.target, c.eye))) * np.tan(np.radians(c.fov_y_deg) / 2)
        cases.append(("ortho", scene, Camera.orthographic(c.eye, c.target, c.up, half, half, c.near, c.far)))
    rng = np.random.default_rng(1234)
    n = 300
    centers = rng.uniform([-2, -1.5, -8], [2, 1.5, -0.05], (n, 1, 3))
    soup = Scene.from_arrays((centers + rng.normal(scale=0.6, size=(n, 3, 3))).reshape(-1, 3).astype(np.float32),
                             np.arange(3 * n).reshape(-1, 3))
    soup.add_random_lights(64, seed=5, radius=(0.5, 2.0))
    soup.add_spot_light((0, 3, -2), (0, -1, -0.6), (4, 4, 4), 10, 20, 40, shadow=True, shadow_map_size=128)
    # shadow maps, spot and sun: 128² keeps the Oclgrind runs of the three soup cases short in CI
    soup.set_sun((0.3, -1, -0.4), (0.8, 0.8, 0.8), shadow_map_size=128)
    cases.append(("soup", soup, Camera.look_at((0, 0, 0), (0, 0, -1), near=0.1, far=50)))
    m = 3000                                 # every triangle over the same few pixels: one hot tile
    tri = np.array([[-0.05, -0.05, 0], [0.05, -0.05, 0], [0, 0.05, 0]], np.float32)
    depth = rng.uniform(-5, -2, m).astype(np.float32)
    dense = Scene.from_arrays((tri[None] + np.stack([np.zeros(m), np.zeros(m), depth], 1)[:, None]).reshape(-1, 3)
                              .astype(np.float32), np.arange(3 * m).reshape(-1, 3))
    dense.add_point_light((0, 0, -1), (1, 1, 1), 3.0)
    cases.append(("dense", dense, Camera.look_at((0, 0, 0), (0, 0, -1), near=0.1, far=50)))
    lights = Scene.from_arrays(np.array([[-4, -1, 0], [4, -1, 0], [4, -1, -10], [-4, -1, -10]], np.float32),
                               [[0, 1, 2], [0, 2, 3]])
    lights.add_random_lights(2000, seed=9, radius=(0.2, 1.5), intensity=0.5)
    lights.add_light_particles(200, seed=3, radius=(0.5, 1.0))
    cases.append(("lights", lights, Camera.look_at((0, 1.5, 1), (0, -1, -5), near=0.1, far=50)))
    cases.append(("glass", _transparent_case(rng), Camera.look_at((0, 0, 0), (0, 0, -1), near=0.1, far=50)))
    cases.append(("materials", _materials_case(rng), Camera.look_at((0, 0.5, 1.5), (0, 0, -3), near=0.1, far=50)))
    # The glTF BRDF under an HDR environment (docs/shading.md): the prefilter kernels, the
    # environment's ambient light, reflections and background.
    lit = _materials_case(rng)
    lit.set_environment(_check_environment(rng), intensity=0.8, rotation_deg=25.0)
    cases.append(("environment", lit, Camera.look_at((0, 0.5, 1.5), (0, 0, -3), near=0.1, far=50)))
    # The glTF surface layers (docs/shading.md): every layer, each with a texture, under lights, a
    # shadowed spot and the environment (kernels/surface_layers.cl, its sheen table), and a
    # transparent layered material (forward.h's SURFACE_LAYERS build).
    cases.append(("layers", _layers_case(rng), Camera.look_at((0, 0.5, 1.5), (0, 0, -3), near=0.1, far=50)))
    # See-through glTF materials (docs/transmission.md): thin, volume (attenuation, dispersion, roughness: the
    # mip chain), textured transmission and thickness, a transmissive BLEND film and a BLEND strip, lit and
    # under the environment (the TRANSMISSION variants of forward.h, abuffer.cl and composite.cl).
    cases.append(("transmission", _transmission_case(rng), Camera.look_at((0, 0.5, 1.5), (0, 0, -3), near=0.1,
                                                                          far=50)))
    # Skins, morph targets and animated weights posed by the device (kernels/pose.cl), with the
    # velocity of the two poses.
    worm = REPO_SCENES / "worm.gltf"
    if worm.is_file():
        skinned = load_scene(worm)
        sun = skinned.sun           # a 128² map, as the soup's: Oclgrind rasterizes it too
        skinned.set_sun(sun.direction, sun.color, shadow_map_size=128)
        skinned.pose(0.7, dt=1 / 24)
        cases.append(("skinned", skinned, skinned.camera))
    return cases


def _check_environment(rng, height: int = 16) -> np.ndarray:
    """A small HDR environment: a sky gradient, a bright sun-like spot and texel noise."""
    from clrender.scene.environment import directions_of_texels
    d = directions_of_texels(height, 2 * height)
    sky = 0.5 + 0.5 * np.clip(d[..., 1:2], 0, 1) * np.array([0.5, 0.7, 1.0])
    sun = 40.0 * (d @ np.array([0.48, 0.6, -0.64]) > 0.97)[..., None]
    return (sky + sun + rng.uniform(0, 0.2, d.shape)).astype(np.float32)


def _materials_case(rng) -> Scene:
    """A bumpy, tilted sheet of glTF-style materials (docs/materials.md): noise metallic-roughness,
    normal, occlusion and emissive textures through texture transforms and a second uv set,
    vertex colours, generated tangents, an unlit strip, point lights and a shadowed spot."""
    from clrender.scene.model import Material, Texture, UVTransform
    n = 12
    u, v = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    positions = np.stack([u * 6 - 3, v * 4 - 2 + 0.3 * np.sin(7 * u), -3 - 2 * v], -1).reshape(-1, 3)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], -1).reshape(-1, 4)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    uv0 = np.stack([u, v], -1).reshape(-1, 2)
    scene = Scene.from_arrays(positions.astype(np.float32), faces, uvs=uv0.astype(np.float32))

    def noise(srgb):
        return Texture("noise", rng.integers(0, 256, (16, 16, 4), dtype=np.uint8), srgb=srgb)

    scene.textures = [noise(True), noise(False), noise(False), noise(False), noise(True)]
    moved = UVTransform(texcoord=1, offset=(0.1, 0.2), rotation=0.4, scale=(1.5, 0.75))
    scene.extra_uvs = (uv0[None] * (2.0, 1.0)).astype(np.float32)
    scene.colors = rng.uniform(0.3, 1.0, (len(positions), 4)).astype(np.float32)
    scene.materials = [Material.from_metallic_roughness(
        "pbr", (0.9, 0.8, 0.6, 1.0), 0.7, 0.8, base_color_texture=0, metallic_roughness_texture=1,
        normal_texture=2, normal_scale=0.8, occlusion_texture=3, occlusion_strength=0.7, emissive=(0.3, 0.2, 0.1),
        emissive_texture=4, emissive_strength=2.0, metallic_roughness_uv=moved, normal_uv=UVTransform(scale=(2, 2)),
        emissive_uv=moved), Material("unlit", (0.2, 0.7, 0.4, 1.0), unlit=True)]
    scene.triangle_material = (np.arange(len(faces)) % n == 0).astype(np.int32)
    scene.add_random_lights(24, seed=4, radius=(1.0, 3.0), intensity=2.0)
    scene.add_spot_light((0, 3, 0), (0, -1, -1), (5, 5, 5), 12, 20, 40, shadow=True, shadow_map_size=128)
    return scene


def _layers_case(rng) -> Scene:
    """_materials_case's sheet with every surface layer on its glTF material (factors and the
    noise textures in the layer slots), a transparent layered strip, under the environment."""
    from dataclasses import replace
    from clrender.scene.model import UVTransform
    scene = _materials_case(rng)
    pbr = replace(scene.materials[0], ior=1.7, specular_factor=0.8, specular_texture=1, specular_color=(1.4, 0.9, 0.7),
                  specular_color_texture=0, clearcoat=0.8, clearcoat_texture=3, clearcoat_roughness=0.3,
                  clearcoat_roughness_texture=1, clearcoat_normal_texture=2, clearcoat_normal_scale=0.5,
                  sheen_color=(0.6, 0.4, 0.9), sheen_color_texture=4, sheen_roughness=0.5, sheen_roughness_texture=3,
                  iridescence=0.9, iridescence_texture=3, iridescence_thickness_texture=1,
                  anisotropy_strength=0.7, anisotropy_rotation=0.6, anisotropy_texture=2,
                  anisotropy_uv=UVTransform(scale=(2, 2)))
    glass = replace(pbr, name="layered glass", alpha_mode="BLEND", base_color=(0.5, 0.7, 0.9, 0.5))
    scene.materials = [pbr, scene.materials[1], glass]
    scene.triangle_material = np.where(np.arange(len(scene.triangle_material)) % 5 == 1, 2,
                                       scene.triangle_material).astype(np.int32)
    scene.set_environment(_check_environment(rng), intensity=0.8, rotation_deg=25.0)
    return scene


def _transmission_case(rng) -> Scene:
    """A textured glTF backdrop behind see-through materials: a thin glass pane, a rough dispersive
    volume box with attenuation (its object scaled: SceneObject.volume_scale), a transmissive BLEND film
    with transmission and thickness textures, a BLEND strip; random lights, a shadowed spot, the environment."""
    from clrender.scene.model import Material, SceneObject, Texture
    quad_uv = np.array([[0, 1], [1, 1], [1, 0], [0, 1], [1, 0], [0, 0]], np.float64)
    tris, uvs, mats, meshes = [], [], [], []

    def add(verts, uv, material, mesh):
        tris.append(np.asarray(verts, np.float64).reshape(-1, 3, 3))
        uvs.append(np.asarray(uv, np.float64).reshape(-1, 3, 2))
        mats.append(np.full(len(tris[-1]), material))
        meshes.append(np.full(len(tris[-1]), mesh))

    def quad(x0, x1, y0, y1, z, turn=0.0):
        c, s = np.cos(turn), np.sin(turn)
        cx = 0.5 * (x0 + x1)
        p = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y0], [x1, y1], [x0, y1]], np.float64)
        return np.stack([cx + (p[:, 0] - cx) * c, p[:, 1], z - (p[:, 0] - cx) * s], -1)

    n = 8                                    # the backdrop: a wavy textured grid over the view
    u, v = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    grid = np.stack([u * 16 - 8, v * 10 - 5, -6 + 0.4 * np.sin(6 * u)], -1)
    cells = [(i, j) for i in range(n) for j in range(n)]
    add([[grid[j, i], grid[j, i + 1], grid[j + 1, i + 1], grid[j, i], grid[j + 1, i + 1], grid[j + 1, i]]
         for i, j in cells], [[(u[j, i], v[j, i]), (u[j, i + 1], v[j, i + 1]), (u[j + 1, i + 1], v[j + 1, i + 1]),
                               (u[j, i], v[j, i]), (u[j + 1, i + 1], v[j + 1, i + 1]), (u[j + 1, i], v[j + 1, i])]
                              for i, j in cells], 0, 0)
    add(quad(-2.2, -0.4, -1.0, 1.0, -2.5, 0.5), quad_uv, 1, 1)              # thin glass
    corners = np.array([[x, y, z] for x in (-0.7, 0.7) for y in (-0.9, 0.9) for z in (-0.5, 0.5)])
    box_faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                 [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    t = np.radians(30.0)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    add((corners @ rot.T + (0.9, -0.2, -3.0))[box_faces], np.zeros((12, 3, 2)), 2, 2)   # volume box
    add(quad(-0.5, 2.5, 0.6, 1.6, -1.8), quad_uv, 3, 1)                                 # textured film
    add(quad(-3.0, 3.0, -1.4, -1.0, -2.0), quad_uv * 2, 4, 0)                             # BLEND strip
    tris, uvs = np.concatenate(tris), np.concatenate(uvs)
    scene = Scene.from_arrays(tris.reshape(-1, 3).astype(np.float32), np.arange(3 * len(tris)).reshape(-1, 3),
                              uvs=uvs.reshape(-1, 2).astype(np.float32))
    scene.textures = [Texture("noise", rng.integers(0, 256, (16, 16, 4), dtype=np.uint8), srgb=True),
                      Texture("mask", rng.integers(0, 256, (8, 8, 4), dtype=np.uint8), srgb=False)]
    scene.materials = [
        Material.from_metallic_roughness("backdrop", (0.9, 0.85, 0.8, 1.0), 0.0, 0.6, base_color_texture=0),
        Material.from_metallic_roughness("glass", (0.9, 0.95, 1.0, 1.0), 0.0, 0.0, transmission=1.0),
        Material.from_metallic_roughness("gem", (0.95, 0.9, 0.95, 1.0), 0.0, 0.35, transmission=1.0, ior=1.6,
                                         thickness=0.8, attenuation_color=(0.6, 0.8, 0.9), attenuation_distance=1.2,
                                         dispersion=1.0),
        Material.from_metallic_roughness("film", (0.7, 0.9, 0.8, 0.8), 0.1, 0.2, alpha_mode="BLEND",
                                         transmission=0.9, transmission_texture=1, thickness=0.3, thickness_texture=1),
        Material.from_metallic_roughness("strip", (0.9, 0.4, 0.2, 0.5), 0.0, 0.5, alpha_mode="BLEND")]
    scene.triangle_material = np.concatenate(mats).astype(np.int32)
    scene.mesh_names = ["backdrop", "glass", "gem"]
    scene.triangle_mesh = np.concatenate(meshes).astype(np.int32)
    scene.objects = [SceneObject("backdrop", "backdrop", "backdrop"), SceneObject("glass", "glass", "glass"),
                     SceneObject("gem", "gem", "gem", volume_scale=1.5)]
    scene.mesh_object = np.arange(3, dtype=np.int32)
    scene.add_random_lights(12, seed=6, radius=(1.0, 3.0), intensity=2.0)
    scene.add_spot_light((0, 3, 0), (0, -1, -1), (5, 5, 5), 12, 20, 40, shadow=True, shadow_map_size=128)
    scene.set_environment(_check_environment(rng), intensity=0.8, rotation_deg=25.0)
    scene.validate()
    return scene


def _transparent_case(rng) -> Scene:
    """Overlapping BLEND triangles (some lists longer than the A-buffer's private sort) over an
    opaque wall, a shadowed spot light and point lights: the transparency passes."""
    from dataclasses import replace
    n = 90
    wall = np.array([[-9, -9, -12], [9, -9, -12], [9, 9, -12], [-9, 9, -12]], np.float32)
    centers = rng.uniform([-1.5, -1.5, -9], [1.5, 1.5, -2], (n, 3))
    tris = (centers[:, None, :] + rng.uniform(-2.5, 2.5, (n, 3, 3))).astype(np.float32)
    scene = Scene.from_arrays(np.vstack([wall, tris.reshape(-1, 3)]),
                              np.vstack([[[0, 1, 2], [0, 2, 3]], 4 + np.arange(3 * n).reshape(-1, 3)]))
    base = scene.materials[0]
    scene.materials = [base] + [replace(base, name=f"glass{k}", base_color=(*rng.uniform(0.2, 1, 3), 1.0),
                                        opacity=float(rng.uniform(0.1, 0.6))) for k in range(4)]
    scene.triangle_material = np.concatenate([[0, 0], 1 + np.arange(n) % 4]).astype(np.int32)
    scene.add_point_light((0, 0, -4), (2, 2, 2), 8.0)
    scene.add_spot_light((2, 3, 0), (-0.2, -0.3, -1), (6, 6, 6), 20, 20, 35, shadow=True, shadow_map_size=128)
    return scene


# Every AOV of the table (clrender.abi.aovs) is compared, with its tolerance above, except those
# the host computes from compared ones.
NOT_COMPARED = {"linear_depth": "depth's distance along the ray (host, from depth)",
                "position": "world position (host, from depth and the camera)"}
AOVS = tuple(name for name in aov_table.NAMES if name not in NOT_COMPARED)
if set(AOVS) != set(TOLERANCES):
    raise AssertionError(f"clrender.tools.check.TOLERANCES and the AOV table disagree: "
                         f"{sorted(set(AOVS) ^ set(TOLERANCES))}")


def run_check(devices="all", scenes: Sequence[str | Path] = (), width: int = 96,
              height: int = 64, progress=None, only: Sequence[str] = ()) -> CheckReport:
    """Render the cases (or `scenes`) on every selected device -- "all", a name (select_devices), or
    a list of DeviceInfo -- and compare with the first device; `only`: just the cases so named."""
    from clrender.device.core import no_device_error
    from clrender.device.probe import select_devices
    from clrender.loaders import load_scene
    from clrender.render.renderer import Renderer

    # Unlike test runs, a portability check includes simulators such as Oclgrind in "all".
    if isinstance(devices, (list, tuple)):
        infos = list(devices)
    else:
        infos = select_devices(devices or "all", simulators=True)
    infos = sorted(infos, key=lambda d: d.is_simulator)   # a real device is the reference
    if not infos:
        raise no_device_error()
    if scenes:
        cases = []
        for s in scenes:
            scene = load_scene(s)
            cases.append((Path(s).stem, scene, scene.default_camera()))
    else:
        cases = default_cases(width, height)
    if not scenes and cases and cases[0][0] == "demo":
        cases.append(("post", cases[0][1], cases[0][2]))          # the demo with every post effect
        cases += [(name, cases[0][1], cases[0][2]) for name in VARIANT_OPTIONS]
    soup = next((c for c in cases if c[0] == "soup"), None) if not scenes else None
    if soup is not None:
        cases += [(mode, soup[1], soup[2]) for mode in LIGHT_VARIANTS]
    if only:
        unknown = set(only) - {c[0] for c in cases}
        if unknown:
            raise ValueError(f"no check case named {sorted(unknown)} (cases: {[c[0] for c in cases]})")
        cases = [c for c in cases if c[0] in only]
    frames = {}
    options = {"post": POST_OPTIONS, **VARIANT_OPTIONS, **{mode: dict(ssao=True, light_culling=mode)
                                                          for mode in LIGHT_VARIANTS}}
    for info in infos:
        renderers: dict = {}           # built on first use (building compiles programs: slow on simulators)
        for name, scene, camera in cases:
            if progress:
                progress(f"{info.label}: {name}")
            key = name if name in options else None
            if key not in renderers:     # the plain cases: SSAO on, so that `ao` is computed
                renderers[key] = Renderer(width, height, device=info, **options.get(key, dict(ssao=True)))
            if name == "post":
                prev = Camera.look_at(np.add(camera.eye, (0.3, 0.0, 0.0)), np.add(camera.target, (0.3, 0.0, 0.0)),
                                      camera.up, camera.fov_y_deg, camera.near, camera.far)
                frames[info.label, name] = renderers[key].render(scene, camera, previous_camera=prev, time=0.5)
            else:
                frames[info.label, name] = renderers[key].render(scene, camera, time=0.5)
    reference = infos[0].label
    rows = []
    for info in infos[1:]:
        for name, _, _ in cases:
            ref, got = frames[reference, name], frames[info.label, name]
            for aov in AOVS:
                max_abs, max_rel, over, text, ok = compare(aov, getattr(ref, aov), getattr(got, aov),
                                                           POST_TOLERANCES if name == "post" else None)
                rows.append(CheckRow(info.label, name, aov, max_abs, max_rel, over, text, ok))
    return CheckReport(reference=reference, devices=tuple(i.label for i in infos), rows=tuple(rows))
