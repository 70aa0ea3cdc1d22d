"""KHR_materials_diffuse_transmission (issue 38; docs/shading.md "Surface layers") in the frame: one more
surface layer, shaded by the surface-layers pass in every pipeline, against the README's formulas and the
independent float64 reference tests/reference/layered.py.

- A thin double-sided quad lit only from behind by a sun shows sun · (−N·L) · dtc/π · dt · (1 − F(V·H')) on its
  front (H' at the light mirrored through the surface, where the Sample Renderer evaluates the Fresnel), written
  out here from the README and compared with the reference too; black with diffuse transmission 0; the textures
  multiply the factors; with the sun's shadow maps on, an opaque square behind it shadows the light coming
  through, and the quad does not shadow itself (the lookup from the side the light enters); BLEND fragments
  (A-buffer, depth peeling) show alpha times the same.
- diffuse transmission 0 on a layered material is that material bit for bit, also in runs of pixels that mix it
  with a transmitting material, with shadows and an environment.
- Deferred, light pre-pass and light-indexed agree (the last two bit for bit; deferred within 45 dB: its 8-bit
  G-buffer base colour), as for the other layers.
- Spheres under a coloured environment (the light through the surface is the irradiance from behind) and a sun:
  the thresholds of tests/test_surface_layers.py; a frame without the transmitted terms fails them.
"""
from __future__ import annotations

import numpy as np
import pytest

from clrender import RenderConfig, Renderer
from clrender.scene.material import Material
from clrender.scene.model import Scene
from layered_cases import CAMERA, frame_inputs, psnr, sphere_grid
from reference.layered import Environment, make_surface, shade_layered
from test_surface_layers import coloured_environment

W, H = 96, 64
BACK_SUN = (0.3, -0.25, 0.92)         # travels towards +z: it lights the quad (normal +z) from behind
LEAF = dict(base_color=(0.2, 0.6, 0.1, 1.0), metallic=0.0, roughness=0.5, double_sided=True)
DTC = (1.0, 0.2, 0.1)


OCCLUDER = (0.2, -0.3, -1.0, 1.0)     # centre x, y, plane z, side of an opaque square behind the quad


def quad(materials, cells=24, size=3.0, columns=None, occluder=None, textures=()) -> Scene:
    """A square in the z = 0 plane facing +z (the camera), `cells` x `cells` cells; cell column i takes
    material columns[i % len(columns)] (default: all material 0). occluder: (x, y, z, side) of one more square
    (the last material) parallel to it."""
    squares = [(0.0, 0.0, 0.0, size, cells, columns or [0])]
    if occluder is not None:
        squares.append((*occluder, 2, [len(materials) - 1]))
    pos, faces, mats = [], [], []
    for cx, cy, z, side, n, cols in squares:
        xs = np.linspace(-side / 2, side / 2, n + 1)
        X, Y = np.meshgrid(xs + cx, xs + cy)
        first = sum(len(p) for p in pos)
        pos.append(np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], 1))
        for j in range(n):
            for i in range(n):
                v0 = first + j * (n + 1) + i
                faces += [(v0, v0 + 1, v0 + n + 2), (v0, v0 + n + 2, v0 + n + 1)]
                mats += [cols[i % len(cols)]] * 2
    pos = np.concatenate(pos).astype(np.float32)
    nrm = np.tile(np.float32([0.0, 0.0, 1.0]), (len(pos), 1))
    scene = Scene(pos, nrm, np.zeros((len(pos), 2), np.float32), np.array(faces, np.int32),
                  np.array(mats, np.int32), list(materials), list(textures))
    scene.ambient = 0.0
    return scene


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def readme_back_light(n, v, direction, color, dt, dtc, dw=1.0, f0=0.04):
    """The README's diffuse_btdf(dtc) = dtc/π for light and view on opposite sides, mixed in by dt, inside the
    dielectric's fresnel_mix (no specular for light from behind): I |N·L| dtc/π dt dw (1 − F(V·H')),
    F = Schlick(f0, 1), H' = normalize(L − 2 (N·L) N + V) (metallic 0, no other layer)."""
    L = -unit(direction)
    nl = n @ L
    lm = L[None] - 2 * nl[:, None] * n
    x = np.clip(np.sum(v * unit(lm + v), 1), 0, 1)
    F = f0 + (1 - f0) * (1 - x) ** 5
    return np.asarray(color) * (-nl * dt * dw * (1 - F))[:, None] * np.asarray(dtc) / np.pi


def interior(frame, margin=2):
    """The quad's pixels at least `margin` pixels from its edge (flattened mask)."""
    fg = frame.triangle_id >= 0
    keep = fg.copy()
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            keep &= np.roll(np.roll(fg, dy, 0), dx, 1)
    return keep


@pytest.fixture(scope="module")
def renderer(device):
    return Renderer(W, H, device=device.id)


def test_back_lit_quad_is_the_readme_formula(renderer):
    mats = [Material("leaf", **LEAF, diffuse_transmission=1.0, diffuse_transmission_color=DTC)]
    scene = quad(mats)
    scene.set_sun(BACK_SUN, (3.0, 3.0, 3.0), shadow=False)
    frame = renderer.render(scene, CAMERA)
    x = frame_inputs(frame)
    assert frame.stats["surface_layers_ms"] > 0 and len(x["normal"]) > 1500
    truth = readme_back_light(x["normal"], x["view"], BACK_SUN, (3.0, 3.0, 3.0), 1.0, DTC)
    ref = shade_layered(make_surface(c=LEAF["base_color"][:3], m=0.0, r=0.5, N=x["normal"], V=x["view"], dt=1.0,
                                     dtc=DTC), lights=[dict(type="sun", direction=BACK_SUN, color=(3.0, 3.0, 3.0))])
    np.testing.assert_allclose(ref, truth, rtol=1e-12)          # the reference is the README's formula here
    got = frame.color[x["mask"]].astype(np.float64)
    assert truth[:, 0].min() > 0.5                              # lit through: a black frame fails
    # float32 kernels against float64 (the G-buffer's normal of a flat quad is exact): measured 9e-8
    np.testing.assert_allclose(got, truth, rtol=1e-5, atol=1e-7)

    scene.materials = [Material("opaque leaf", **LEAF, diffuse_transmission=0.0, diffuse_transmission_color=DTC)]
    dark = renderer.render(scene, CAMERA)
    assert dark.color[x["mask"]].max() == 0.0 and "surface_layers_ms" not in dark.stats


def test_back_light_is_shadowed_by_what_lies_behind(renderer):
    """With the sun's shadow maps on, an opaque square behind the quad shadows the light coming through it where
    the square blocks the sun (black there), and the quad is not in its own shadow elsewhere (the lookup uses the
    flipped normal: the offset and bias of the side the light enters): there it equals the frame without shadows."""
    mats = [Material("leaf", **LEAF, diffuse_transmission=0.8, diffuse_transmission_color=DTC),
            Material("wall", base_color=(0.5, 0.5, 0.5, 1.0), metallic=0.0, roughness=0.5, double_sided=True)]
    frames = []
    for shadow in (False, True):
        scene = quad(mats, occluder=OCCLUDER)
        scene.set_sun(BACK_SUN, (3.0, 3.0, 3.0), shadow=shadow)
        frames.append(renderer.render(scene, CAMERA))
    keep = interior(frames[0]) & (frames[0].material_id == 0)
    p = frames[0].position[keep].astype(np.float64)
    L = -unit(BACK_SUN)
    q = p + L * ((OCCLUDER[2] - p[:, 2]) / L[2])[:, None]        # where the ray to the sun meets the square's plane
    inside = np.max(np.abs(q[:, :2] - OCCLUDER[:2]), 1) - OCCLUDER[3] / 2     # < 0: the square blocks the sun
    free, shadowed = frames[0].color[keep], frames[1].color[keep]
    assert free[:, 0].min() > 0.3 and (inside < -0.1).sum() > 100 and (inside > 0.1).sum() > 500
    assert shadowed[inside < -0.1].max() == 0.0
    np.testing.assert_allclose(shadowed[inside > 0.1], free[inside > 0.1], rtol=1e-6)


@pytest.mark.parametrize("pipeline", ["deferred", "light_prepass"])
def test_zero_transmission_is_the_material_without_it(device, pipeline):
    """A clearcoat material with diffuse transmission 0 (colour set) is the clearcoat material bit for bit, and its
    pixels do not change when every other cell column of the quad transmits (the runs of pixels mix both), under
    a front sun with shadows, a point light behind and an environment."""
    cc = dict(LEAF, clearcoat=0.6, clearcoat_roughness=0.3)
    plain = Material("coat", **cc)
    zero = Material("coat dt0", **cc, diffuse_transmission=0.0, diffuse_transmission_color=(0.3, 0.9, 0.1))
    leaf = Material("coat leaf", **cc, diffuse_transmission=0.7, diffuse_transmission_color=DTC)
    r = Renderer(W, H, device=device.id, config=RenderConfig(pipeline=pipeline))
    frames = {}
    for name, mats in (("plain", [plain, plain]), ("zero", [zero, zero]), ("mixed", [zero, leaf])):
        scene = quad(mats, columns=[0, 1])
        scene.set_sun((-0.3, -0.4, -0.87), (2.0, 2.0, 2.0), shadow=True)
        scene.add_point_light((0.4, 0.3, -1.5), (4.0, 3.0, 2.0), 10.0)
        scene.set_environment(coloured_environment(16))
        frames[name] = r.render(scene, CAMERA)
    assert np.array_equal(frames["zero"].color, frames["plain"].color)
    own = frames["mixed"].material_id == 0
    layered = np.isin(frames["mixed"].material_id, [0, 1])
    assert own.sum() > 500 and (layered & ~own).sum() > 500
    assert np.array_equal(frames["mixed"].color[own], frames["plain"].color[own])
    assert np.abs(frames["mixed"].color[layered & ~own] - frames["plain"].color[layered & ~own]).max() > 1e-2


def dt_materials():
    """Spheres sweeping the transmission and its colour, with other layers on some."""
    base = dict(base_color=(0.3, 0.6, 0.2, 1.0), metallic=0.0, roughness=0.5, double_sided=True)
    sweep = [dict(diffuse_transmission=t) for t in (0.25, 0.5, 1.0)] + [
        dict(diffuse_transmission=0.8, diffuse_transmission_color=DTC),
        dict(diffuse_transmission=0.6, diffuse_transmission_color=(0.2, 0.5, 1.0), roughness=0.2),
        dict(diffuse_transmission=0.7, clearcoat=0.8, clearcoat_roughness=0.2),
        dict(diffuse_transmission=0.7, sheen_color=(0.6, 0.6, 0.9), sheen_roughness=0.5),
        dict(diffuse_transmission=0.5, diffuse_transmission_color=DTC, metallic=0.4)]
    return [Material(f"dt{k}", **{**base, **kw}) for k, kw in enumerate(sweep)]


def reference(frame, materials, lights=(), environment=None, transmission=True, sample=None):
    """(rendered, reference, material index) over the layered pixels (or `sample` of them, seeded: the
    reference's environment sums are the slow part)."""
    x = frame_inputs(frame)
    idx = np.arange(len(x["material"]))
    if sample is not None and len(idx) > sample:
        idx = np.sort(np.random.default_rng(1).choice(idx, sample, replace=False))
    mat = x["material"][idx]
    get = lambda key: np.asarray([getattr(m, key) for m in materials], np.float64)[mat]      # noqa: E731
    params = dict(c=np.asarray([m.base_color[:3] for m in materials], np.float64)[mat], m=get("metallic"),
                  r=get("roughness"), cc=get("clearcoat"), ccr=get("clearcoat_roughness"), shc=get("sheen_color"),
                  shr=get("sheen_roughness"), dt=get("diffuse_transmission") * transmission,
                  dtc=get("diffuse_transmission_color"))
    ref = shade_layered(make_surface(N=x["normal"][idx], V=x["view"][idx], P=x["position"][idx], **params),
                        lights=lights, environment=environment)
    return frame.color[x["mask"]].astype(np.float64)[idx], ref, mat


def check(got, ref, mat, overall, each):
    assert np.isfinite(got).all()
    total = psnr(got, ref)
    spheres = {int(k): psnr(got[mat == k], ref[mat == k]) for k in np.unique(mat)}
    assert total >= overall and min(spheres.values()) >= each, (total, spheres)
    return total, spheres


def test_environment_and_sun_against_the_reference(device):
    """A coloured environment (brighter above) and a sun from behind-left: the transmitted light is the
    irradiance from the far hemisphere and the sun through the surface. The thresholds of the other layers under
    a coloured environment and a sun (40 / 35 dB: clrender's order-2 SH and prefiltered mips against the
    reference's sums; measured 71 / 49 dB on Debian PoCL); the reference without the transmitted terms is outside
    them (32 dB)."""
    mats = dt_materials()
    scene = sphere_grid(mats)
    pixels = coloured_environment()
    scene.set_environment(pixels)
    sun = (0.5, -0.3, 0.81)                     # from behind the spheres (travels towards the camera)
    scene.set_sun(sun, (1.5, 1.5, 1.5), shadow=False)
    frame = Renderer(192, 96, device=device.id).render(scene, CAMERA)
    lights = [dict(type="sun", direction=sun, color=(1.5, 1.5, 1.5))]
    env = Environment.equirect(pixels)
    got, ref, mat = reference(frame, mats, lights, env, sample=2400)
    check(got, ref, mat, 40.0, 35.0)
    _, without, _ = reference(frame, mats, lights, env, transmission=False, sample=2400)
    assert psnr(got, without) < 35.0, psnr(got, without)


def test_every_pipeline_shades_the_same_transmission(device):
    mats = dt_materials()[3:6] + [Material("plain", base_color=(0.3, 0.6, 0.2, 1.0), metallic=0.0, roughness=0.5)]
    scene = sphere_grid(mats)
    scene.set_sun((0.4, -0.5, 0.77), (3.0, 3.0, 3.0), shadow=True)
    scene.set_environment(coloured_environment(16))
    frames = {p: Renderer(192, 96, device=device.id, config=RenderConfig(pipeline=p)).render(scene, CAMERA)
              for p in ("deferred", "light_prepass", "light_indexed")}
    ref = frames["light_prepass"]
    layered = np.isin(ref.material_id, [0, 1, 2])
    assert layered.sum() > 1000 and all("surface_layers_ms" in f.stats for f in frames.values())
    assert np.array_equal(frames["light_indexed"].color[layered], ref.color[layered])
    deferred = frames["deferred"].color[layered].astype(np.float64)
    assert psnr(deferred, ref.color[layered].astype(np.float64)) >= 45.0


def srgb_to_linear(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def test_textures_multiply_the_factors(renderer):
    """diffuseTransmissionTexture's A (linear) multiplies the factor, diffuseTransmissionColorTexture's RGB (sRGB)
    the colour (constant textures: the filtering cannot blur them)."""
    from clrender.scene.model import Texture
    texel_a, texel_c = np.uint8([10, 200, 30, 128]), np.uint8([255, 128, 64, 255])
    m = Material("leaf", **LEAF, diffuse_transmission=0.9, diffuse_transmission_color=(0.8, 1.0, 1.0),
                 diffuse_transmission_texture=0, diffuse_transmission_color_texture=1)
    scene = quad([m], textures=[Texture("dt", np.tile(texel_a, (4, 4, 1)), srgb=False),
                                Texture("dtc", np.tile(texel_c, (4, 4, 1)), srgb=True)])
    scene.set_sun(BACK_SUN, (3.0, 3.0, 3.0), shadow=False)
    frame = renderer.render(scene, CAMERA)
    x = frame_inputs(frame)
    dt = 0.9 * 128 / 255
    dtc = np.array([0.8, 1.0, 1.0]) * srgb_to_linear(texel_c[:3] / 255.0)
    truth = readme_back_light(x["normal"], x["view"], BACK_SUN, (3.0, 3.0, 3.0), dt, dtc)
    np.testing.assert_allclose(frame.color[x["mask"]], truth, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("mode", ["abuffer", "depth_peeling"])
def test_transparent_fragments_let_the_back_light_through(device, mode):
    """A BLEND quad (alpha 0.5) over an empty background, lit from behind: one fragment per pixel, so the colour
    is 0.5 × the README's transmitted light (forward.h's SURFACE_LAYERS build), in both transparency modes."""
    from test_ibl_shading import view_dirs
    m = Material("blend leaf", **{**LEAF, "base_color": (0.2, 0.6, 0.1, 0.5)}, alpha_mode="BLEND",
                 diffuse_transmission=1.0, diffuse_transmission_color=DTC)
    scene = quad([m])
    scene.set_sun(BACK_SUN, (3.0, 3.0, 3.0), shadow=False)
    frame = Renderer(W, H, device=device.id, config=RenderConfig(transparency=mode)).render(scene, CAMERA)
    d = view_dirs(CAMERA, W, H).reshape(-1, 3)
    eye = np.asarray(CAMERA.eye, np.float64)
    p = eye + (-eye[2] / d[:, 2])[:, None] * d                  # the view ray meets the plane z = 0
    hit = np.max(np.abs(p[:, :2]), 1) < 1.4                     # inside the quad, away from its edge
    assert hit.sum() > 1000
    n = np.tile([0.0, 0.0, 1.0], (hit.sum(), 1))
    truth = 0.5 * readme_back_light(n, -d[hit], BACK_SUN, (3.0, 3.0, 3.0), 1.0, DTC)
    np.testing.assert_allclose(frame.color.reshape(-1, 3)[hit], truth, rtol=1e-4, atol=1e-6)
