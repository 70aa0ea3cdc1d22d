"""The glTF surface layers (issue 37; docs/shading.md "Surface layers") in the frame, against the
independent float64 reference tests/reference/layered.py (written from the extension READMEs):
a grid of spheres sweeping each layer's parameters under a sun, a uniform and a coloured
environment; every pipeline and transparency mode; degenerate values; multiple scattering; and
that a scene without layers runs (and builds) nothing new.

Tolerance: the reference reads the frame's normal, position and view (the G-buffer's 24-bit
octahedral normal: under 0.05°) and the materials' exact factors; the deferred kernels shade the
G-buffer's surface (8-bit sRGB base colour, 8-bit roughness). Measured PSNR (Debian PoCL 3.1,
192x96, over covered pixels / worst sphere): sun 66-74 / 59 dB; uniform environment 64-69 / 49 dB (the DFG table's bilinear lookups); coloured environment
45-52 / 40 dB (clrender's order-2 SH irradiance and prefiltered mips against the reference's
brute-force sums). Asserted: 40 dB over the covered pixels and 35 dB for every sphere."""
import sys

import numpy as np
import pytest

from clrender import RenderConfig, Renderer
from clrender.scene.material import Material
from layered_cases import BASE, CAMERA, SUN_DIRECTION, centers, frame_inputs, layer_materials, psnr, sphere_grid
from reference.layered import Environment, make_surface, shade_layered

W, H = 192, 96
SUN = dict(type="sun", direction=SUN_DIRECTION, color=(3.0, 3.0, 3.0))
# Material field -> the reference's surface parameter
FIELD = dict(ior="ior", specular_factor="sw", specular_color="sc", clearcoat="cc", clearcoat_roughness="ccr",
             sheen_color="shc", sheen_roughness="shr", iridescence="irid", iridescence_thickness_max="d",
             iridescence_ior="irid_ior", anisotropy_strength="aniso", anisotropy_rotation="aniso_rot",
             metallic="m", roughness="r", diffuse_transmission="dt")
LAYERS = ("specular", "clearcoat", "sheen", "iridescence", "anisotropy", "diffuse_transmission")


def coloured_environment(h=32, seed=3) -> np.ndarray:
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from test_ibl_shading import smooth_environment
    return smooth_environment(h, seed)


def reference(frame, materials, lights=(), environment=None, sample=None, seed=1):
    """(rendered, reference, material index) over the layered pixels (or `sample` of them)."""
    x = frame_inputs(frame)
    keep = np.array([bool(materials[k].layers) for k in x["material"]])
    idx = np.nonzero(keep)[0]
    if sample is not None and len(idx) > sample:
        idx = np.sort(np.random.default_rng(seed).choice(idx, sample, replace=False))
    mat = x["material"][idx]
    p = x["position"][idx]
    d = p - np.array(centers(len(materials)))[mat]
    t = np.stack([-d[:, 2], np.zeros(len(d)), d[:, 0]], 1)      # sphere_grid's analytic tangents
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    params = {name: np.asarray([getattr(m, key) for m in materials], np.float64)[mat] for key, name in FIELD.items()}
    params["sc"] = np.asarray([m.specular_color for m in materials], np.float64)[mat]
    params["shc"] = np.asarray([m.sheen_color for m in materials], np.float64)[mat]
    params["dtc"] = np.asarray([m.diffuse_transmission_color for m in materials], np.float64)[mat]
    c = np.asarray([m.base_color[:3] for m in materials], np.float64)[mat]
    surf = make_surface(c=c, N=x["normal"][idx], V=x["view"][idx], T=t, P=p, **params)
    ref = shade_layered(surf, lights=lights, environment=environment)
    return frame.color[x["mask"]].astype(np.float64)[idx], ref, mat


def check(got, ref, mat, overall=40.0, each=35.0):
    assert np.isfinite(got).all()
    total = psnr(got, ref)
    spheres = {int(k): psnr(got[mat == k], ref[mat == k]) for k in np.unique(mat)}
    assert total >= overall and min(spheres.values()) >= each, (total, spheres)


@pytest.fixture(scope="module")
def renderer(device):
    return Renderer(W, H, device=device.id)


@pytest.mark.parametrize("layer", LAYERS)
def test_layers_under_a_sun(renderer, layer):
    mats = layer_materials(layer)
    scene = sphere_grid(mats)
    scene.set_sun(SUN_DIRECTION, (3.0, 3.0, 3.0), shadow=False)
    frame = renderer.render(scene, CAMERA)
    assert frame.stats["surface_layers_ms"] > 0
    got, ref, mat = reference(frame, mats, lights=[SUN], sample=1000)
    assert ref.max() > 0.5                          # lit: a black frame fails
    check(got, ref, mat, overall=60.0, each=50.0)   # measured >= 77 / 60 dB


@pytest.mark.parametrize("layer", LAYERS)
def test_layers_under_a_uniform_environment(renderer, layer):
    mats = layer_materials(layer)
    scene = sphere_grid(mats)
    radiance = np.array([0.7, 0.56, 0.42], np.float32)
    scene.set_environment(np.tile(radiance, (16, 32, 1)))
    frame = renderer.render(scene, CAMERA)
    got, ref, mat = reference(frame, mats, environment=Environment.uniform(radiance), sample=1500)
    check(got, ref, mat, overall=50.0, each=45.0)   # measured >= 64 / 49 dB


@pytest.mark.parametrize("layer", LAYERS)
def test_layers_under_a_coloured_environment_and_a_sun(renderer, layer):
    mats = layer_materials(layer)
    scene = sphere_grid(mats)
    pixels = coloured_environment()
    scene.set_environment(pixels)
    scene.set_sun(SUN_DIRECTION, (1.5, 1.5, 1.5), shadow=False)
    frame = renderer.render(scene, CAMERA)
    got, ref, mat = reference(frame, mats, lights=[dict(SUN, color=(1.5, 1.5, 1.5))],
                              environment=Environment.equirect(pixels), sample=1200)
    check(got, ref, mat)


def test_degenerate_layer_values_are_the_base_material_exactly(renderer):
    """clearcoat 0, sheen colour 0, specular 1 / white / IOR 1.5, iridescence 0, anisotropy 0: no layer,
    the same bits as the plain material (and no surface-layers pass)."""
    plain = Material("plain", **BASE)
    degenerate = Material("degenerate", **BASE, clearcoat=0.0, clearcoat_roughness=0.7, sheen_color=(0.0, 0.0, 0.0),
                          sheen_roughness=0.4, specular_factor=1.0, specular_color=(1.0, 1.0, 1.0), ior=1.5,
                          iridescence=0.0, iridescence_ior=1.8, anisotropy_strength=0.0, anisotropy_rotation=1.0)
    assert degenerate.layers == frozenset()
    frames = []
    for m in (plain, degenerate):
        scene = sphere_grid([m, m])
        scene.set_sun(SUN_DIRECTION, (3.0, 3.0, 3.0), shadow=False)
        scene.set_environment(coloured_environment(16))
        frames.append(renderer.render(scene, CAMERA))
    assert "surface_layers_ms" not in frames[1].stats
    assert np.array_equal(frames[0].color, frames[1].color) and frames[0].color.max() > 0.1


def test_emission_is_darkened_by_the_clearcoat(renderer):
    """Emission × (1 − cc·Fc(N·V)) (KHR_materials_clearcoat); no light, no ambient."""
    mats = [Material(f"e{c}", **BASE, emissive=(1.0, 0.5, 0.25), emissive_strength=4.0, clearcoat=c)
            for c in (0.5, 1.0)]
    scene = sphere_grid(mats)
    frame = renderer.render(scene, CAMERA)
    x = frame_inputs(frame)
    nv = np.clip((x["normal"] * x["view"]).sum(1), 0.0, 1.0)
    fc = 0.04 + 0.96 * (1.0 - nv) ** 5
    cc = np.array([0.5, 1.0])[x["material"]]
    expect = 4.0 * np.array([1.0, 0.5, 0.25]) * (1.0 - cc * fc)[:, None]
    got = frame.color[x["mask"]]
    # deferred reads the emission from the G-buffer's 8-bit sRGB plane (~0.5% at 0.25) and N.V from
    # the unquantized normal: 1% away from grazing, 3% at the silhouette
    np.testing.assert_allclose(got[nv > 0.3], expect[nv > 0.3], rtol=1e-2)
    np.testing.assert_allclose(got, expect, rtol=3e-2)
    assert got[:, 0].min() < 4.0 * (1 - 0.5 * 0.04) - 0.05     # darkened at grazing angles


def test_every_pipeline_shades_the_same_layers(device):
    """The layers are shaded after each pipeline's opaque pass: the light pre-pass and light-indexed
    rebuild the surface from the visibility buffer (the same bits on the layered pixels); deferred
    reads it from its G-buffer (8-bit base colour and roughness: within 45 dB of the others)."""
    mats = layer_materials("clearcoat")[:3] + [Material("plain", **BASE)]
    scene = sphere_grid(mats)
    scene.set_sun(SUN_DIRECTION, (3.0, 3.0, 3.0), shadow=True)
    scene.set_environment(coloured_environment(16))
    frames = {p: Renderer(W, H, device=device.id, config=RenderConfig(pipeline=p)).render(scene, CAMERA)
              for p in ("deferred", "light_prepass", "light_indexed")}
    ref = frames["light_prepass"]
    layered = np.isin(ref.material_id, [0, 1, 2])
    assert layered.sum() > 1000 and all("surface_layers_ms" in f.stats for f in frames.values())
    assert np.array_equal(frames["light_indexed"].color[layered], ref.color[layered])
    deferred = frames["deferred"].color[layered].astype(np.float64)
    assert psnr(deferred, ref.color[layered].astype(np.float64)) >= 45.0


@pytest.mark.parametrize("mode", ["abuffer", "depth_peeling"])
def test_transparent_layered_fragments(device, mode):
    """A single-sided BLEND clearcoat sphere over an empty background: one fragment per pixel, so the
    colour is alpha × the layered reference (forward.h with SURFACE_LAYERS), in both transparency modes."""
    m = Material("glassy", base_color=(0.8, 0.35, 0.2, 0.6), metallic=0.0, roughness=0.4, alpha_mode="BLEND",
                 double_sided=False, clearcoat=1.0, clearcoat_roughness=0.3, sheen_color=(0.3, 0.6, 0.9),
                 sheen_roughness=0.5)
    scene = sphere_grid([m])
    scene.set_sun(SUN_DIRECTION, (3.0, 3.0, 3.0), shadow=False)
    frame = Renderer(W, H, device=device.id, config=RenderConfig(transparency=mode)).render(scene, CAMERA)
    from test_ibl_shading import view_dirs
    d = view_dirs(CAMERA, W, H).reshape(-1, 3)                # the unit sphere hit analytically per pixel
    center = np.array(centers(1)[0])
    eye = np.asarray(CAMERA.eye, np.float64) - center
    b = d @ eye
    disc = b * b - (eye @ eye - 1.0)
    hit = disc > 0.05                                         # away from the tessellated silhouette
    dist = -b[hit] - np.sqrt(disc[hit])
    p = eye + dist[:, None] * d[hit]                          # relative to the centre: the normal
    assert hit.sum() > 500
    t = np.stack([-p[:, 2], np.zeros(len(p)), p[:, 0]], 1)
    surf = make_surface(c=(0.8, 0.35, 0.2), m=0.0, r=0.4, N=p, V=-d[hit], T=t, P=p + center, cc=1.0, ccr=0.3,
                        shc=(0.3, 0.6, 0.9), shr=0.5)
    ref = 0.6 * shade_layered(surf, lights=[SUN])
    got = frame.color.reshape(-1, 3)[hit].astype(np.float64)
    assert psnr(got, ref) >= 35.0, psnr(got, ref)     # the mesh's interpolated normals vs the analytic sphere


def test_multiscatter_white_furnace(device):
    """RenderConfig.multiscatter: a white rough metal under a uniform white environment reflects
    >= 0.98 (Fdez-Agüera's compensation); without it single scattering loses up to ~70% at roughness 1."""
    mats = [Material(f"metal{r}", (1.0, 1.0, 1.0, 1.0), metallic=1.0, roughness=r) for r in (0.25, 0.5, 0.75, 1.0)]
    scene = sphere_grid(mats)
    scene.set_environment(np.ones((16, 32, 3), np.float32))
    for on in (False, True):
        frame = Renderer(W, H, device=device.id, config=RenderConfig(multiscatter=on)).render(scene, CAMERA)
        x = frame_inputs(frame)
        nv = (x["normal"] * x["view"]).sum(1)
        c = frame.color[x["mask"]][nv > 0.2]
        assert c.max() <= 1.0 + 1e-3                        # never more than it receives
        if on:
            assert c.min() >= 0.98, c.min()
        else:
            assert c.min() < 0.5 and "surface_layers_ms" not in frame.stats


def test_layer_furnace_never_reflects_more_than_it_receives(renderer):
    """Each layer over a white base under a uniform white environment: <= 1 + 1% (the reference's
    energy tests hold the model; this holds the kernels)."""
    kw = dict(base_color=(1.0, 1.0, 1.0, 1.0), metallic=0.0)
    mats = [Material("cc", **kw, roughness=0.5, clearcoat=1.0, clearcoat_roughness=0.3),
            Material("sheen", **kw, roughness=0.5, sheen_color=(1.0, 1.0, 1.0), sheen_roughness=0.5),
            Material("irid", **kw, roughness=0.3, iridescence=1.0, iridescence_thickness_max=400.0),
            Material("aniso", (1.0, 1.0, 1.0, 1.0), metallic=1.0, roughness=0.5, anisotropy_strength=0.8),
            Material("spec", **kw, roughness=0.5, specular_factor=0.5, specular_color=(1.0, 1.0, 1.0), ior=1.8)]
    scene = sphere_grid(mats)
    scene.set_environment(np.ones((16, 32, 3), np.float32))
    frame = renderer.render(scene, CAMERA)
    x = frame_inputs(frame)
    nv = (x["normal"] * x["view"]).sum(1)
    c = frame.color[x["mask"]][nv > 0.1]
    assert 0.5 < c.max() <= 1.01, c.max()


def test_a_scene_without_layers_builds_and_launches_nothing_new(device):
    scene = sphere_grid([Material("plain", **BASE)])
    scene.set_sun(SUN_DIRECTION, (3.0, 3.0, 3.0), shadow=False)
    r = Renderer(W, H, device=device.id)
    frame = r.render(scene, CAMERA)
    assert "surface_layers_ms" not in frame.stats
    layers_pass = next(p for p in r.pipeline.passes if p.name == "surface_layers")
    assert layers_pass.kernel._kernel is None and not layers_pass.lut_made     # never launched, never resolved


def sheen_table() -> np.ndarray:
    """E(mu_i, r_j) on the kernels' 32 x 32 grid from the reference's quadrature (float64)."""
    from reference.layered import sheen_albedo
    g = (np.arange(32) + 0.5) / 32
    mu, r = np.meshgrid(g, g)               # row j: roughness r_j; column i: mu_i
    return sheen_albedo(mu.ravel(), r.ravel()).reshape(32, 32)


@pytest.mark.oclgrind
def test_sheen_table_kernel_first_rows(device, capfd):
    """The device's sheen albedo table (sheen_albedo_lut) against the reference's quadrature: the
    first 64 entries (two roughness rows: the whole table costs minutes under Oclgrind; the
    default device's full table is checked by the frames above and tests/test_layered_brdf_kernel.py)."""
    import pyopencl.array as cla
    from clrender.passes.base import launch_1d
    from clrender.device.probe import open_device
    from clrender.passes.surface_layers import SurfaceLayersPass
    from test_oclgrind_tier import assert_no_device_diagnostics
    dev = open_device(device.id)
    layers = SurfaceLayersPass(dev, RenderConfig())
    lut = cla.zeros(dev.queue, 32 * 32, np.float32)
    layers.lut_kernel(dev.queue, *launch_1d(64), lut.data)
    got = lut.get().reshape(32, 32)[:2]
    assert_no_device_diagnostics(capfd)
    np.testing.assert_allclose(got, sheen_table()[:2], rtol=1e-4, atol=5e-6)


def test_layer_kernels_on_a_tiny_frame(device, capfd):
    """For Oclgrind (`pytest tests/test_surface_layers.py -k tiny --device oclgrind`: 7.5 minutes on
    this 2-core machine, so not in .ci/run's tier, which runs the sheen table's test above; the
    suite runs it on the default device): the surface-layers kernel
    on a tiny frame with every layer (and layer textures), a sun and an environment (the shadow-map
    lookups it shares with lighting.h run in the other tier tests; forward.h's SURFACE_LAYERS build
    is compared across implementations by `clrender check`'s layers case); no diagnostics, and the
    untextured layered sphere against the reference. The sheen table
    is the reference's (set in the pass: computing it costs minutes under the simulator;
    test_sheen_table_kernel_first_rows checks the kernel)."""
    from dataclasses import replace
    from clrender.scene.model import Texture
    from test_oclgrind_tier import assert_no_device_diagnostics
    table = sheen_table().astype(np.float32).ravel()

    def renderer():
        r = Renderer(24, 12, device=device.id)
        layers = next(p for p in r.pipeline.passes if p.name == "surface_layers")
        layers.sheen_lut.set(table, queue=layers.queue)
        layers.lut_made = True
        return r
    rng = np.random.default_rng(4)
    full = Material("all", **BASE, ior=1.8, specular_factor=0.7, clearcoat=0.8, clearcoat_roughness=0.3,
                    sheen_color=(0.5, 0.6, 0.9), sheen_roughness=0.5, iridescence=0.8, iridescence_thickness_max=350.0,
                    anisotropy_strength=0.6, anisotropy_rotation=0.4)
    textured = replace(full, name="textured", clearcoat_normal_texture=0, sheen_color_texture=1, anisotropy_texture=0,
                       iridescence_thickness_texture=0)
    scene = sphere_grid([full, full], lat=8, lon=16)
    scene.uvs = rng.uniform(0, 1, (len(scene.positions), 2)).astype(np.float32)
    scene.textures = [Texture("n", rng.integers(0, 256, (8, 8, 4), dtype=np.uint8), srgb=False),
                      Texture("c", rng.integers(0, 256, (8, 8, 4), dtype=np.uint8), srgb=True)]
    scene.materials = [full, textured]
    scene.set_sun(SUN_DIRECTION, (2.0, 2.0, 2.0), shadow=False)
    radiance = np.array([0.5, 0.45, 0.4], np.float32)
    scene.set_environment(np.tile(radiance, (8, 16, 1)))
    frame = renderer().render(scene, CAMERA)
    assert_no_device_diagnostics(capfd)
    assert frame.stats["surface_layers_ms"] > 0 and np.isfinite(frame.color).all()
    got, ref, mat = reference(frame, scene.materials, lights=[dict(SUN, color=(2.0, 2.0, 2.0))],
                              environment=Environment.uniform(radiance))
    got, ref = got[mat == 0], ref[mat == 0]               # the untextured sphere
    assert len(got) > 10 and psnr(got, ref) >= 30.0     # 8 x 16 facets against the reference's frame normals
