"""Hatching (report IV.3, Praun et al. 2001): the tonal art maps' nesting and tones
(clrender/passes/tam.py), and kernels/hatching.cl through the Renderer against an independent NumPy
version of its per-pixel formula (docs/post.md's LDR chain, "Hatching").

The image must read as a drawing: pixels without geometry (triangle id -1) are the white paper,
whatever the tone-mapped background holds; foreground pixels on a G-buffer discontinuity with a
direct neighbour (edge_aa.cl's test: background neighbour, relative depth jump, normal angle;
inked on the nearer side) are black ink, checked against an independent NumPy mask from the
Frame's linear_depth / normal / triangle_id; the rest of the objects keep their strokes over
the desaturated colour. `assert_reads_as_drawing` is shown to reject a black frame, the old
hatched-everywhere frame, blank paper and strokes without outlines."""
from __future__ import annotations

import math

import numpy as np
import pytest

import clrender
from clrender import Camera, Material, Scene
from clrender.passes import tam
from clrender.abi.gbuffer import linear_to_srgb8
from clrender.passes.hatching import mip_levels
from reference import aa
from reference.shading import tonemap_curve

LUMA = np.array([0.2126, 0.7152, 0.0722])          # linear Rec. 709 / sRGB luminance


# --- the tonal art map ---------------------------------------------------------------------------

def test_tam_shapes_and_range():
    maps = tam.tonal_art_map()
    assert len(maps) == tam.TONES == 7
    for tone in maps:
        assert len(tone) == tam.LEVELS
        for level, m in enumerate(tone):
            n = tam.SIZE >> level
            assert m.shape == (n, n) and m.dtype == np.float32
            assert 0.0 <= m.min() and m.max() <= 1.0
    flat = tam.device_layout()
    assert flat.size == tam.TONES * tam.LEVEL_TEXELS and flat.nbytes == tam.DEVICE_BYTES
    # the device layout: tone-major, levels from level 0 at the documented offsets
    for t in (0, 3, 6):
        for level in (0, 1, 5, tam.LEVELS - 1):
            n = tam.SIZE >> level
            start = t * tam.LEVEL_TEXELS + tam.level_offset(level)
            np.testing.assert_array_equal(flat[start:start + n * n].reshape(n, n), maps[t][level])


def test_tam_nesting_at_every_level():
    """Every inked texel of tone t is inked in tone t + 1, at every mip level; stronger, the
    coverage never decreases texel by texel (what makes the blended ink monotone)."""
    maps = tam.tonal_art_map()
    for t in range(tam.TONES - 1):
        for level in range(tam.LEVELS):
            lighter, darker = maps[t][level], maps[t + 1][level]
            assert not np.any((lighter > 0) & (darker == 0)), (t, level)
            assert np.all(darker >= lighter), (t, level)
            if level < 4:                       # the new strokes really add ink at this level
                assert np.count_nonzero(darker > lighter) > 0.05 * darker.size, (t, level)


def test_tam_coverage_strictly_increases_with_tone():
    maps = tam.tonal_art_map()
    for level in range(tam.LEVELS):
        means = np.array([maps[t][level].mean(dtype=np.float64) for t in range(tam.TONES)])
        assert means[0] == 0.0, "tone 0 is blank paper"
        assert np.all(np.diff(means) > 0.1), (level, means)
        assert means[-1] > 0.9, means
    # coverage tracks the tone targets (mean of level 0 within one stroke's worth of ink)
    level0 = np.array([maps[t][0].mean(dtype=np.float64) for t in range(tam.TONES)])
    np.testing.assert_allclose(level0, tam.TARGETS, atol=0.01)


def test_tam_mips_are_box_filtered():
    maps = tam.tonal_art_map()
    for t in (1, 4, 6):
        for level in range(1, tam.LEVELS):
            fine = maps[t][level - 1].astype(np.float64)
            n = fine.shape[0] // 2
            np.testing.assert_allclose(maps[t][level], fine.reshape(n, 2, n, 2).mean(axis=(1, 3)), rtol=0, atol=1e-6)


def test_tam_is_tileable_and_stroked():
    """Strokes wrap around the tile edges: across the seam neighbouring texels agree as well as
    inside; and the map is strokes (mostly blank or inked texels), not a flat grey."""
    m = tam.tonal_art_map()[2][0].astype(np.float64)
    inside = np.abs(np.diff(m, axis=1)).mean()
    seam = np.abs(m[:, 0] - m[:, -1]).mean()
    assert seam < 1.5 * inside, (seam, inside)
    inside_v = np.abs(np.diff(m, axis=0)).mean()
    assert np.abs(m[0] - m[-1]).mean() < 1.5 * inside_v
    assert ((m < 0.05) | (m > 0.6)).mean() > 0.7         # anti-aliased edges are the rest


def test_tam_is_deterministic():
    first = tam.device_layout().copy()
    tam.tonal_art_map.cache_clear()
    tam.device_layout.cache_clear()
    np.testing.assert_array_equal(tam.device_layout(), first)


def test_mip_level_choice():
    assert mip_levels(1.0) == (0, 1.0, 1, 0.5, 0.0)
    assert mip_levels(3.0)[::2] == (0, 1, 0.0)                 # magnified: level 0 only
    assert mip_levels(0.5) == (1, 1.0, 2, 0.5, 0.0)
    level0, k0, level1, k1, frac = mip_levels(0.7)
    assert (level0, level1) == (0, 1) and frac == pytest.approx(math.log2(1 / 0.7))
    assert k0 == pytest.approx(1 / 0.7) and k1 == pytest.approx(1 / 1.4)
    assert mip_levels(1e-4)[0] == tam.LEVELS - 1 and mip_levels(1e-4)[4] == 0.0


# --- the per-pixel formula, independently in NumPy ---------------------------------------------

def hatching_reference(ldr: np.ndarray, scale: float, saturation: float) -> np.ndarray:
    """(H, W, 3) hatched linear colour for tone-mapped linear `ldr` (H, W, 3), float64.

    Y = clamp(luma(c), 0, 1), tone = 6(1 - Y) blended between its two nearest tones' maps, each
    sampled bilinearly (wrapped) at ((x + ½)/s, (y + ½)/s) level-0 texels on mip level
    log2(1/s) (trilinear, clamped to [0, last level]); out = (1 + sat·(c - 1))·(1 - ink)."""
    maps = tam.tonal_art_map()
    h, w = ldr.shape[:2]
    luma = np.clip(ldr.astype(np.float64) @ LUMA, 0.0, 1.0)
    tone = (1.0 - luma) * 6.0
    t = np.minimum(np.floor(tone), 5).astype(int)
    f = tone - t
    lam = min(max(-math.log2(scale), 0.0), tam.LEVELS - 1)
    levels = [(int(lam), 1.0 - (lam - int(lam)))]
    if lam > int(lam):
        levels.append((int(lam) + 1, lam - int(lam)))

    def sample(tones: np.ndarray) -> np.ndarray:
        ink = np.zeros((h, w))
        for level, weight in levels:
            stack = np.stack([maps[k][level] for k in range(tam.TONES)]).astype(np.float64)
            n = stack.shape[1]
            u = (np.arange(w) + 0.5) / (scale * 2**level) - 0.5
            v = (np.arange(h) + 0.5) / (scale * 2**level) - 0.5
            iu, iv = np.floor(u).astype(int), np.floor(v).astype(int)
            wu, wv = (u - iu)[None, :], (v - iv)[:, None]
            cols0, cols1 = iu % n, (iu + 1) % n
            rows0, rows1 = (iv % n)[:, None], ((iv + 1) % n)[:, None]
            top = stack[tones, rows0, cols0] * (1 - wu) + stack[tones, rows0, cols1] * wu
            bottom = stack[tones, rows1, cols0] * (1 - wu) + stack[tones, rows1, cols1] * wu
            ink += weight * (top * (1 - wv) + bottom * wv)
        return ink

    ink = sample(t) * (1 - f) + sample(t + 1) * f
    return (1.0 + saturation * (ldr - 1.0)) * (1.0 - ink)[..., None]


# --- paper and outlines, independently in NumPy ---------------------------------------------------

PAPER, INK = 255, 0


def _neighbour(a: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """a[y + dy, x + dx], coordinates clamped to the image (a border pixel is its own neighbour)."""
    pad = ((1, 1), (1, 1)) + ((0, 0),) * (a.ndim - 2)
    p = np.pad(a, pad, mode="edge")
    h, w = a.shape[:2]
    return p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]


def outline_masks(linear_depth, normal, triangle_id, depth_threshold=0.05, normal_threshold_deg=30.0):
    """(ink, ambiguous) (H, W) bool masks of the outline rule: a foreground pixel is ink when one of
    its 4 direct neighbours (clamped) is background, or is foreground, not nearer (z_n >= z) and
    either |z_n - z| > t·min(z, z_n) (z = Frame.linear_depth, float32 like the kernel) or the angle
    between the normals exceeds the threshold. `ambiguous`: pixels with a pair within float
    round-off of a threshold (decoding and normalizing the normals on the device may round the
    other way)."""
    z = np.asarray(linear_depth, np.float32)
    n = np.asarray(normal, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    fg = np.asarray(triangle_id) >= 0
    t32, cos_t = np.float32(depth_threshold), math.cos(math.radians(normal_threshold_deg))
    ink, ambiguous = np.zeros(fg.shape, bool), np.zeros(fg.shape, bool)
    h, w = fg.shape
    ys, xs = np.mgrid[0:h, 0:w]
    for dy, dx in ((0, -1), (0, 1), (-1, 0), (1, 0)):
        itself = ((ys + dy < 0) | (ys + dy >= h) | (xs + dx < 0) | (xs + dx >= w))
        z1, n1, fg1 = _neighbour(z, dy, dx), _neighbour(n, dy, dx), _neighbour(fg, dy, dx)
        front = fg & fg1 & (z1 >= z) & ~itself
        with np.errstate(invalid="ignore"):
            jump = np.abs(z1 - z) > t32 * np.minimum(z, z1)                   # float32, as the kernel
            rel = np.abs(z1.astype(np.float64) - z) / (depth_threshold * np.minimum(z, z1))
        cos = (n * n1).sum(-1)
        ink |= (fg & ~fg1 & ~itself) | (front & jump) | (front & (cos < cos_t))
        ambiguous |= front & ((np.abs(rel - 1.0) < 1e-4) | (np.abs(cos - cos_t) < 1e-4))
    return ink, ambiguous & fg


def frame_outline(frame, config_kw=None):
    """outline_masks for a Frame rendered with RenderConfig thresholds `config_kw` (defaults)."""
    kw = config_kw or {}
    return outline_masks(frame.linear_depth, frame.normal, frame.triangle_id,
                         kw.get("edge_depth_threshold", 0.05), kw.get("edge_normal_threshold_deg", 30.0))


def expected_image(frame, ldr, scale=1.0, saturation=0.3, config_kw=None):
    """(expected uint8 image, ink mask, ambiguous mask): paper where triangle_id is -1, ink on the
    outline, hatching_reference elsewhere."""
    ink, ambiguous = frame_outline(frame, config_kw)
    hatched = hatching_reference(ldr, scale, saturation)
    bg = frame.triangle_id < 0
    out = np.where(bg[..., None], 1.0, np.where(ink[..., None], 0.0, hatched))
    return linear_to_srgb8(out), ink, ambiguous


def assert_matches_expected(image, frame, ldr, scale=1.0, saturation=0.3, config_kw=None):
    """Background exactly paper white, (unambiguous) outline pixels exactly ink, the other pixels
    the NumPy hatching within one 8-bit code; an ambiguous pixel may be either ink or hatched."""
    expect, ink, ambiguous = expected_image(frame, ldr, scale, saturation, config_kw)
    bg = frame.triangle_id < 0
    assert (image[bg] == PAPER).all(), f"{(image[bg] != PAPER).any(-1).sum()} background pixels are not paper"
    sure_ink = ink & ~ambiguous
    assert (image[sure_ink] == INK).all(), f"{(image[sure_ink] != INK).any(-1).sum()} outline pixels are not ink"
    hatched = hatching_reference(ldr, scale, saturation)
    as_hatched = np.abs(image.astype(int) - linear_to_srgb8(hatched).astype(int)).max(-1) <= 1
    either = ambiguous & ((image == INK).all(-1) | as_hatched)
    diff = np.abs(image.astype(int) - expect.astype(int)).max(-1)
    bad = (diff > 1) & ~either
    assert not bad.any(), (int(bad.sum()), diff[bad].max(), np.argwhere(bad)[:5])
    return ink


def assert_reads_as_drawing(image, frame, config_kw=None):
    """What makes the hatched image a drawing, from the Frame's G-buffer AOVs alone: the
    background is paper, the outline (outline_masks) is ink, and the objects' interiors (foreground,
    1 pixel away from the outline) keep strokes: inked texels and paper between them, not blank,
    not solid black."""
    bg = frame.triangle_id < 0
    ink, ambiguous = frame_outline(frame, config_kw)
    assert bg.sum() > 0.05 * bg.size and ink.sum() > 20, "the scene must show background and outlines"
    assert (image[bg] == PAPER).all(), "the background is not white paper"
    sure_ink = ink & ~ambiguous
    assert (image[sure_ink] == INK).all(), "an outline pixel is not ink"
    interior = ~bg & ~aa.dilate(ink | bg, 1)
    assert interior.sum() > 0.1 * interior.size
    grey = image[interior].astype(np.float64).mean(-1)
    assert (grey < 200).mean() > 0.1, "the objects are not hatched (blank paper)"
    assert (grey > 60).mean() > 0.1, "the objects are solid ink (no paper between the strokes)"


def coloured_scene() -> Scene:
    from test_supersample import hard_edged_scene
    return hard_edged_scene()


COLOURED_CAMERA = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=70.0, near=0.1, far=50.0)


@pytest.mark.parametrize("scale,saturation", [(1.0, 0.3), (0.7, 0.0), (2.5, 1.0), (0.25, 0.3), (1e-3, 0.5)])
def test_matches_numpy_formula(make_renderer, scale, saturation):
    """Frame.image equals the NumPy formula applied to the tone-mapped Frame.color, within one
    8-bit code, on the objects; the background (the top and bottom strips: the wall ends) is
    paper and the outlines ink (until the outlines, this test compared every pixel with the
    formula, which hatched the empty background black: tone 6). Scales cover level 0, trilinear
    levels 0-1, magnification, level 2 and the 1×1 level."""
    w, h = 71, 43                                    # not a multiple of VEC: the row tails too
    frame = make_renderer(w, h, hatching=True, hatching_scale=scale, hatching_saturation=saturation).render(
        coloured_scene(), COLOURED_CAMERA)
    ldr = tonemap_curve(frame.color, "reinhard")
    ink = assert_matches_expected(frame.image, frame, ldr, scale, saturation)
    bg = frame.triangle_id < 0
    assert bg.sum() > 100 and ink.sum() > 50, (bg.sum(), ink.sum())
    expect = linear_to_srgb8(hatching_reference(ldr, scale, saturation))
    plain = linear_to_srgb8(ldr)
    fg = ~bg & ~ink
    assert np.abs(expect[fg].astype(int) - plain[fg].astype(int)).mean() > 10, "hatching changes the image"
    assert "hatching_ms" in frame.stats and "encode_ms" in frame.stats


# aa_scene (tests/reference/aa.py): flat shapes at several depths, a back wall leaving the right
# part of the frame empty, and a folded roof whose faces meet with continuous depth and a 60°
# normal change (an edge only for the normal test); ambient light only (colour = albedo).
AA_TONEMAP = dict(tonemap="clamp")


@pytest.mark.parametrize("config_kw", [{}, dict(edge_depth_threshold=0.8, edge_normal_threshold_deg=70.0),
                                       dict(supersample=2), dict(bloom=True, bloom_threshold=0.3, bloom_strength=2.0)])
def test_paper_background_and_ink_outlines(device, config_kw):
    """On aa_scene at an odd size: background exactly paper, the NumPy outline mask exactly ink,
    the rest the hatching formula; the roof's ridge is inked only when the normal threshold is
    below its 60° fold; with over-sampling the pass reads the resolved G-buffer; with a bloom
    that lights the background (a stand-in for an environment behind the objects) the background
    stays paper."""
    w, h = 61, 45
    scene, cam = aa.aa_scene(w / h), aa.aa_camera()
    frame = clrender.Renderer(w, h, device=device.id, hatching=True, **AA_TONEMAP, **config_kw).render(scene, cam)
    ldr = np.clip(frame.color.astype(np.float64), 0.0, 1.0)
    depth_t = config_kw.get("edge_depth_threshold", 0.05)
    normal_t = config_kw.get("edge_normal_threshold_deg", 30.0)
    rel_margin, angle_margin = aa.threshold_margin(frame.depth, frame.normal, frame.triangle_id, depth_t, normal_t)
    assert rel_margin > 0.1 and angle_margin > 5.0, "a neighbour pair sits on a threshold"
    ink = assert_matches_expected(frame.image, frame, ldr, config_kw=config_kw)
    assert_reads_as_drawing(frame.image, frame, config_kw)
    bg = frame.triangle_id < 0
    if config_kw.get("bloom"):
        assert ldr[bg].max() > 0.05, "the bloom must reach the background for this case to mean anything"
    # every silhouette pixel on the object side is ink, and ink only on foreground pixels
    silhouette = ~bg & np.any([_neighbour(bg, dy, dx) for dy, dx in ((0, -1), (0, 1), (-1, 0), (1, 0))], 0)
    assert silhouette.sum() > 50 and (frame.image[silhouette] == INK).all()
    assert not (ink & bg).any()
    # the ridge: cyan pixels beside magenta ones, depth continuous (the roof's interior fold)
    mats = scene.triangle_material[np.maximum(frame.triangle_id, 0)]
    names = [m.name for m in scene.materials]
    cyan, magenta = ~bg & (mats == names.index("cyan")), ~bg & (mats == names.index("magenta"))
    ridge = (cyan & (_neighbour(magenta, 0, 1) | _neighbour(magenta, 0, -1)) & ~silhouette) | \
            (magenta & (_neighbour(cyan, 0, 1) | _neighbour(cyan, 0, -1)) & ~silhouette)
    assert ridge.sum() > 10
    # what the normal test adds there (the depth test alone inks the roof's ends against the wall);
    # checked on the mask: a hatched pixel under a stroke's centre can be black too
    without_normals = outline_masks(frame.linear_depth, frame.normal, frame.triangle_id, depth_t, 180.0)[0]
    drawn = ridge & ink & ~without_normals
    assert (frame.image[drawn] == INK).all()
    if normal_t < 60.0:
        assert drawn.sum() >= 0.4 * ridge.sum(), "the ridge is drawn (on one side of each pair)"
    else:
        assert not drawn.any(), "a 60° fold is no edge at a 70° threshold"


def test_environment_background_is_paper(device):
    """With an environment shown behind the objects (Scene.set_environment, where this tree has
    it), the background's tone-mapped colour is the sky, not black; the hatched background is
    still exactly paper and the drawing checks hold."""
    w, h = 61, 45
    scene, cam = aa.aa_scene(w / h), aa.aa_camera()
    if not hasattr(scene, "set_environment"):
        pytest.skip("this tree has no environment (Scene.set_environment)")
    scene.set_environment("studio")
    frame = clrender.Renderer(w, h, device=device.id, hatching=True, **AA_TONEMAP).render(scene, cam)
    bg = frame.triangle_id < 0
    assert frame.color[bg].max() > 0.05, "the environment must show in the background"
    assert (frame.image[bg] == PAPER).all()
    assert_reads_as_drawing(frame.image, frame)


def test_drawing_check_rejects_non_drawings(device):
    """assert_reads_as_drawing fails for a fully black frame, the old output (hatching over every
    pixel, the empty background crossed black), blank paper, and strokes without outlines; and
    assert_matches_expected fails for all of them too."""
    w, h = 61, 45
    scene, cam = aa.aa_scene(w / h), aa.aa_camera()
    frame = clrender.Renderer(w, h, device=device.id, hatching=True, **AA_TONEMAP).render(scene, cam)
    ldr = np.clip(frame.color.astype(np.float64), 0.0, 1.0)
    assert_reads_as_drawing(frame.image, frame)
    bg = frame.triangle_id < 0
    ink, _ = frame_outline(frame)
    everywhere = linear_to_srgb8(hatching_reference(ldr, 1.0, 0.3))
    no_outline = everywhere.copy()
    no_outline[bg] = PAPER
    for name, image in (("black", np.zeros_like(frame.image)), ("hatched everywhere", everywhere),
                        ("blank paper", np.full_like(frame.image, PAPER)), ("no outline", no_outline)):
        with pytest.raises(AssertionError):
            assert_reads_as_drawing(image, frame)
        with pytest.raises(AssertionError):
            assert_matches_expected(image, frame, ldr)
    # solid objects: paper background and ink outlines, but no paper between strokes
    solid = np.where(bg[..., None], PAPER, INK).astype(np.uint8)
    with pytest.raises(AssertionError, match="solid ink"):
        assert_reads_as_drawing(solid, frame)
    assert ink.sum() > 20


@pytest.mark.oclgrind
def test_hatching_kernel_small_frame(device, capfd):
    """The simulator tier (`pytest -m oclgrind --device oclgrind`): hatching.cl on a 22×15 aa_scene
    frame (partial runs and work-groups, clamped borders, the normal test on the roof), paper,
    ink and strokes as above, and no diagnostics from the OpenCL implementation (Oclgrind reports
    invalid accesses, races and uninitialized reads on stderr)."""
    from test_oclgrind_tier import assert_no_device_diagnostics
    w, h = 22, 15
    scene, cam = aa.aa_scene(w / h), aa.aa_camera()
    frame = clrender.Renderer(w, h, device=device.id, tile_size=8, light_tile_size=8, hatching=True,
                              **AA_TONEMAP).render(scene, cam)
    ink = assert_matches_expected(frame.image, frame, np.clip(frame.color.astype(np.float64), 0.0, 1.0))
    assert ink.sum() > 10 and (frame.triangle_id < 0).sum() > 10
    assert_no_device_diagnostics(capfd)


# --- a luminance ramp through the renderer ------------------------------------------------------

RW, RH, PATCHES = 160, 40, 8
RAMP_CAMERA = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=90.0, near=0.1, far=50.0)


def patch_scene(albedos) -> Scene:
    """len(albedos) camera-facing grey quads side by side filling the RW×RH RAMP_CAMERA image,
    lit only by a uniform ambient term of 1 (colour = albedo)."""
    depth, n = 5.0, len(albedos)

    def at(px, py):
        return ((px / RW * 2 - 1) * RW / RH * depth, (1 - py / RH * 2) * depth, -depth)
    verts, faces = [], []
    for i in range(n):
        x0, x1 = i * RW / n, (i + 1) * RW / n
        verts += [at(x0, RH), at(x1, RH), at(x1, 0), at(x0, 0)]
        faces += [[4 * i, 4 * i + 1, 4 * i + 2], [4 * i, 4 * i + 2, 4 * i + 3]]
    scene = Scene.from_arrays(np.array(verts, np.float32), np.array(faces))
    scene.materials = [Material(f"grey{i}", (a, a, a, 1.0), specular_intensity=0.0) for i, a in enumerate(albedos)]
    scene.triangle_material = np.repeat(np.arange(n, dtype=np.int32), 2)
    scene.ambient = 1.0
    return scene


def patch_means(image: np.ndarray, n: int) -> np.ndarray:
    """Mean of each patch's interior (2 pixels in from its edges), per channel averaged."""
    wide = RW // n
    return np.array([image[2:-2, i * wide + 2:(i + 1) * wide - 2].astype(np.float64).mean() for i in range(n)])


def test_luminance_ramp_darkens_monotonically(make_renderer):
    albedos = np.linspace(0.0, 1.0, PATCHES)
    scene = patch_scene(albedos)
    plain = make_renderer(RW, RH, tonemap="clamp").render(scene, RAMP_CAMERA)
    hatched = make_renderer(RW, RH, tonemap="clamp", hatching=True).render(scene, RAMP_CAMERA)
    assert (plain.triangle_id >= 0).all()
    np.testing.assert_allclose(patch_means(plain.color[..., 0], PATCHES), albedos, atol=0.01)
    means = patch_means(hatched.image, PATCHES)
    assert np.all(np.diff(means) > 3), means           # darker as the luminance decreases
    # white paper where the input is white, nearly (not exactly) black where it is black
    assert means[-1] >= 254 and 0 < means[0] < 60, means
    # neither the input nor black: strokes on paper, their mean near the input's for mid tones
    plain_means = patch_means(plain.image, PATCHES)
    for i in range(1, PATCHES - 1):
        patch = hatched.image[2:-2, i * (RW // PATCHES) + 2:(i + 1) * (RW // PATCHES) - 2].astype(np.float64)
        assert patch.std() > 25 and patch.max() > 150, (i, patch.std(), patch.max())
        assert abs(means[i] - plain_means[i]) > 2, (means, plain_means)
    # in linear light the ink coverage reproduces the tone (saturation 0: paper·(1 - ink))
    ink_only = make_renderer(RW, RH, tonemap="clamp", hatching=True, hatching_saturation=0.0).render(
        scene, RAMP_CAMERA)
    linear = patch_means(hatching_reference(plain.color.astype(np.float64), 1.0, 0.0)[..., 0], PATCHES)
    assert np.all(np.diff(linear) > 0.05)
    np.testing.assert_allclose(linear[1:-1], albedos[1:-1], atol=0.08)
    assert np.all(np.diff(patch_means(ink_only.image, PATCHES)) > 3)


def test_desaturates_partly(make_renderer):
    """A saturated red patch keeps `hatching_saturation` of its chroma on the paper."""
    scene = patch_scene([0.5] * 4)
    scene.materials = [Material(f"red{i}", (0.9, 0.08, 0.05, 1.0), specular_intensity=0.0) for i in range(4)]
    out = {}
    for s in (0.0, 0.3, 1.0):
        img = make_renderer(RW, RH, tonemap="clamp", hatching=True, hatching_saturation=s).render(
            scene, RAMP_CAMERA).image.astype(np.float64)
        out[s] = img[..., 0].mean() - img[..., 1].mean()
    assert abs(out[0.0]) < 1.0 and 5 < out[0.3] < out[1.0], out


# --- off: nothing runs ---------------------------------------------------------------------------

def test_off_launches_nothing_and_changes_nothing(make_renderer):
    scene = coloured_scene()
    default = make_renderer(48, 32).render(scene, COLOURED_CAMERA)
    off = make_renderer(48, 32, hatching=False, hatching_scale=3.0, hatching_saturation=0.9).render(
        scene, COLOURED_CAMERA)
    assert "hatching_ms" not in default.stats and "hatching_ms" not in off.stats
    assert "encode_ms" not in off.stats
    np.testing.assert_array_equal(default.image, off.image)
    np.testing.assert_array_equal(default.color, off.color)
    on = make_renderer(48, 32, hatching=True).render(scene, COLOURED_CAMERA)
    np.testing.assert_array_equal(on.color, default.color)         # Frame.color is the HDR colour
    assert not np.array_equal(on.image, default.image)
