"""kernels/transmission.h (issue 38) against float64 formulas written here from the KHR_materials_transmission,
_volume and _dispersion READMEs, through the test kernel kernels/testing/transmission_check.cl:

* seeded random materials, pixels, depths and normals (perspective with an off-centre principal point, and
  orthographic): transmission t, diffuse weight 1 - t, the transmitted weight
  w_c = a t (1 - metallic) base_c (1 - F_c) attenuationColor_c^(d / attenuationDistance) with Schlick's F from
  IOR and KHR_materials_specular, the refracted exit point P + r_c d projected back to pixels (r_c by Snell's law
  in its tangential form, the dispersion READMEs' per-channel IORs), the blur level and the exit-face flag:
  rtol 2e-5 (float32 arithmetic, OpenCL pow/log2), offsets also atol 2e-4 px.
* closed cases: a surface seen along its normal has no offset in any channel (the method is exact there); a plane
  tilted by theta under an orthographic camera is offset by W/2 d sin(theta)(cos(theta)/ior - cos(theta_t)) / tan_x
  (Snell's law by hand); dispersion 0 gives the three channels the same bits; Beer-Lambert through a thickness
  scaled by the node; exit faces of volumes let nothing through and set no lookup, thin back faces shade.
Mutations of the reference (the full spread instead of the README's half, no (1 - metallic), Fresnel at normal
incidence, the thickness without the node's scale) are asserted to fail the comparison. VEC 1 and the device's width.
One render checks the texture slots (transmission R, thickness G, linear) end to end: rtol 1e-5.
"""
from __future__ import annotations

import numpy as np
import pyopencl as cl
import pytest

from clrender.abi.structs import material_tx_dtype
from clrender.device import capabilities
from clrender.device.core import Device
from clrender.passes.base import launch_1d

TC_IN, TC_OUT = 17, 13
W, H = 320, 200
OUT_KEYS = ("t", "kd", "wr", "wg", "wb", "oxr", "oyr", "oxg", "oyg", "oxb", "oyb", "lod", "exit")


@pytest.fixture
def cl_device(device):
    return Device.get(device)


def vec_widths(dev: Device) -> list[int]:
    return sorted({1, capabilities.pixel_vector_width(dev.cl_device)})


def unit(x):
    x = np.asarray(x, np.float64)
    return x / np.linalg.norm(x)


class Camera:
    """A camera as camera_upload packs it: eye, F (unit forward), R tan_x, U tan_y, principal point (cx, cy)."""

    def __init__(self, ortho=False, yaw=0.3, pitch=-0.2, tan_x=0.6, tan_y=0.375, cx=0.0, cy=0.0):
        self.ortho = ortho
        self.eye = np.array([0.4, 1.1, 5.0])
        f = np.array([np.sin(yaw) * np.cos(pitch), np.sin(pitch), -np.cos(yaw) * np.cos(pitch)])
        self.F = unit(f)
        self.R = unit(np.cross(self.F, [0.0, 1.0, 0.0]))
        self.U = np.cross(self.R, self.F)
        self.tan_x, self.tan_y, self.cx, self.cy = tan_x, tan_y, cx, cy

    def block(self) -> np.ndarray:
        c = np.zeros(16, np.float32)
        c[0:3], c[3] = self.eye, self.cx
        c[4:7], c[7] = self.F, self.cy
        c[8:11], c[12:15] = self.R * self.tan_x, self.U * self.tan_y
        return c

    def point(self, px, py, z):
        """The world point at view depth z on pixel (px, py)'s ray, and the unit direction to the eye."""
        xn = (px + 0.5) * 2 / W - 1 - self.cx
        yn = 1 - (py + 0.5) * 2 / H - self.cy
        side = xn * self.tan_x * self.R + yn * self.tan_y * self.U
        if self.ortho:
            return self.eye + side + z * self.F, -self.F
        d = self.F + side
        return self.eye + z * d, -unit(d)

    def pixel(self, X):
        """Continuous pixel coordinates (x right, y down; pixel centres at i + 0.5) of world point X."""
        rel = X - self.eye
        depth = rel @ self.F
        if self.ortho:
            nx, ny = rel @ self.R / self.tan_x, rel @ self.U / self.tan_y
        else:
            nx, ny = rel @ self.R / (depth * self.tan_x), rel @ self.U / (depth * self.tan_y)
        return np.array([(nx + self.cx + 1) * W / 2, (1 - (ny + self.cy)) * H / 2])


def snell(i_dir, n, eta):
    """Refracted unit direction of incident unit direction i_dir through unit normal n (facing against i_dir),
    eta = n1/n2, by the tangential component (eta times the incident's) and the normal one (unit length)."""
    tang = eta * (i_dir - (i_dir @ n) * n)
    s2 = tang @ tang
    if s2 >= 1:
        return np.zeros(3)
    return tang - np.sqrt(1 - s2) * n


def reference(mat, q, cam, half_spread=0.025, metal=True, fresnel_at_view=True, node_scale=True):
    """The header's quantities in float64 from the spec formulas (module doc); mutations for the can-fail test."""
    t = min(max(mat["transmission"] * q["tex_t"], 0.0), 1.0)
    P, v = cam.point(q["px"], q["py"], q["z"])
    n = q["n"]
    volume = mat["thickness"] > 0
    d = mat["thickness"] * q["tex_d"] * (q["scale"] if node_scale else 1.0) if volume else 0.0
    exit_face = volume and q["back"]
    ior, sf = mat["ior"], mat["specular_factor"]
    nv = max(n @ v, 1e-4) if fresnel_at_view else 1.0
    w = np.zeros(3)
    for c in range(3):
        f0 = min(((ior - 1) / (ior + 1)) ** 2 * mat["specular_color"][c], 1.0) * sf
        F = f0 + (sf - f0) * (1 - nv) ** 5
        dist = mat["attenuation_distance"]
        att = mat["attenuation_color"][c] ** (d / dist) if d > 0 and np.isfinite(dist) else 1.0
        w[c] = q["a"] * t * ((1 - q["metallic"]) if metal else 1.0) * q["c"][c] * (1 - F) * att
    if exit_face:
        w[:] = 0
    offs = np.zeros((3, 2))
    if volume and not exit_face:
        g = max(ior, 1.0)
        s = (g - 1) * half_spread * mat["dispersion"]
        for c, ior_c in enumerate((max(g - s, 1.0), g, g + s)):
            exit_point = P + snell(-v, n, 1 / ior_c) * d
            offs[c] = cam.pixel(exit_point) - cam.pixel(P)
    lod = np.log2(max(W, H)) * q["rough"] * min(max(2 * ior - 2, 0.0), 1.0)
    if exit_face or q["a"] <= 0:
        lod = -1.0
    return dict(t=t, kd=1 - t, wr=w[0], wg=w[1], wb=w[2], oxr=offs[0, 0], oyr=offs[0, 1], oxg=offs[1, 0],
                oyg=offs[1, 1], oxb=offs[2, 0], oyb=offs[2, 1], lod=lod, exit=float(exit_face))


def material(**kw):
    m = dict(transmission=1.0, thickness=0.0, attenuation_distance=np.inf, dispersion=0.0,
             attenuation_color=(1.0, 1.0, 1.0), ior=1.5, specular_color=(1.0, 1.0, 1.0), specular_factor=1.0)
    m.update(kw)
    return m


def records(mats) -> np.ndarray:
    """MaterialTx[] for the kernel; the dicts get the float32-rounded values (the reference sees what the device sees)."""
    a = np.zeros(len(mats), material_tx_dtype)
    for i, m in enumerate(mats):
        for k in ("transmission", "thickness", "attenuation_distance", "dispersion", "attenuation_color", "ior",
                  "specular_color", "specular_factor"):
            a[i][k] = m[k]
            m[k] = tuple(float(x) for x in a[i][k]) if np.ndim(a[i][k]) else float(a[i][k])
        a[i]["slots"]["texture"] = -1
    return a


def query(tx=0, px=100, py=80, z=3.0, tex_t=1.0, tex_d=1.0, scale=1.0, back=False, metallic=0.0, rough=0.0,
          c=(1.0, 1.0, 1.0), a=1.0, n=None):
    return dict(tx=tx, px=px, py=py, z=z, tex_t=tex_t, tex_d=tex_d, scale=scale, back=back, metallic=metallic,
                rough=rough, c=np.asarray(c, np.float64), a=a, n=n)


def pack(qs, cam) -> np.ndarray:
    a = np.zeros((len(qs), TC_IN), np.float32)
    for r, q in enumerate(qs):
        if q["n"] is None:
            q["n"] = cam.point(q["px"], q["py"], q["z"])[1]
        a[r] = [q["tx"], q["px"], q["py"], q["z"], q["tex_t"], q["tex_d"], q["scale"], float(q["back"]),
                q["metallic"], q["rough"], *q["c"], q["a"], *q["n"]]
        (_, _, _, q["z"], q["tex_t"], q["tex_d"], q["scale"], _, q["metallic"], q["rough"], c0, c1, c2, q["a"],
         n0, n1, n2) = a[r].astype(np.float64)
        q["c"], q["n"] = np.array([c0, c1, c2]), np.array([n0, n1, n2])
    return a


_KERNELS: dict = {}


def run(dev: Device, vec: int, cam: Camera, mats, qs) -> list[dict]:
    key = (id(dev), vec, cam.ortho)
    if key not in _KERNELS:
        _KERNELS[key] = dev.kernel("testing/transmission_check.cl", "transmission_check",
                                   {"VEC": vec, "ORTHO": int(cam.ortho)})
    mf = cl.mem_flags
    rec = records(mats)
    block = cam.block()
    q = pack(qs, cam)
    bufs = [cl.Buffer(dev.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=x) for x in (rec, block, q)]
    out = np.zeros((len(qs), TC_OUT), np.float32)
    obuf = cl.Buffer(dev.context, mf.WRITE_ONLY, out.nbytes)
    g, l = launch_1d(-(-len(qs) // vec))
    _KERNELS[key](dev.queue, g, l, bufs[0], bufs[1], np.int32(W), np.int32(H), bufs[2], np.int32(len(qs)), obuf)
    cl.enqueue_copy(dev.queue, out, obuf)
    return [dict(zip(OUT_KEYS, row.astype(np.float64))) for row in out]


def camera_as_device(cam: Camera) -> Camera:
    """The reference's camera from the float32 block the device reads (R, U keep their float32 directions)."""
    b = cam.block().astype(np.float64)
    c = Camera(cam.ortho, tan_x=cam.tan_x, tan_y=cam.tan_y, cx=float(b[3]), cy=float(b[7]))
    c.eye, c.F = b[0:3], b[4:7]
    c.tan_x, c.tan_y = np.linalg.norm(b[8:11]), np.linalg.norm(b[12:15])
    c.R, c.U = b[8:11] / c.tan_x, b[12:15] / c.tan_y
    return c


def compare(got, want, rtol=2e-5, atol=2e-5, atol_px=2e-4) -> list[str]:
    bad = []
    for i, (g, w) in enumerate(zip(got, want)):
        for k in OUT_KEYS:
            tol = (atol_px if k.startswith("o") else atol) + rtol * abs(w[k])
            if not abs(g[k] - w[k]) <= tol:
                bad.append(f"query {i} {k}: device {g[k]:.7g} reference {w[k]:.7g}")
    return bad


def random_case(rng, cam: Camera, n=96):
    mats = []
    for _ in range(12):
        volume = rng.random() < 0.7
        mats.append(material(
            transmission=rng.uniform(0.2, 1.0), thickness=rng.uniform(0.05, 2.0) if volume else 0.0,
            attenuation_distance=rng.choice([np.inf, rng.uniform(0.3, 4.0)]),
            dispersion=rng.choice([0.0, rng.uniform(0.1, 2.0)]) if volume else 0.0,
            attenuation_color=tuple(rng.uniform(0.05, 1.0, 3)), ior=rng.choice([1.0, 1.33, rng.uniform(1.05, 2.4)]),
            specular_color=tuple(rng.uniform(0.4, 1.6, 3)), specular_factor=rng.uniform(0.3, 1.0)))
    qs = []
    for _ in range(n):
        px, py, z = int(rng.integers(0, W)), int(rng.integers(0, H)), rng.uniform(1.0, 8.0)
        v = cam.point(px, py, z)[1]
        while True:                                   # a normal facing the viewer, up to ~72 degrees off
            nn = unit(v + 0.9 * rng.normal(size=3))
            if nn @ v > 0.3:
                break
        qs.append(query(tx=int(rng.integers(0, len(mats))), px=px, py=py, z=z, tex_t=rng.uniform(0.3, 1.0),
                        tex_d=rng.uniform(0.2, 1.0), scale=rng.uniform(0.5, 2.0), back=bool(rng.random() < 0.2),
                        metallic=rng.choice([0.0, rng.uniform(0, 1)]), rough=rng.uniform(0, 1),
                        c=rng.uniform(0, 1, 3), a=rng.choice([1.0, rng.uniform(0.1, 1.0)]), n=nn))
    return mats, qs


CAMERAS = {"perspective": dict(ortho=False, cx=0.06, cy=-0.04), "orthographic": dict(ortho=True, tan_x=3.2, tan_y=2.0)}


@pytest.mark.parametrize("view", sorted(CAMERAS))
def test_random_cases_match_float64_spec(cl_device, view):
    for vec in vec_widths(cl_device):
        rng = np.random.default_rng(38)
        cam = Camera(**CAMERAS[view])
        mats, qs = random_case(rng, cam)
        got = run(cl_device, vec, cam, mats, qs)
        ref_cam = camera_as_device(cam)
        want = [reference(mats[q["tx"]], q, ref_cam) for q in qs]
        bad = compare(got, want)
        assert not bad, f"VEC {vec} {view}: {len(bad)} mismatches, first: {bad[:5]}"
        assert sum(w["exit"] for w in want) > 3 and sum(abs(w["oxr"] - w["oxb"]) > 0.1 for w in want) > 5


@pytest.mark.parametrize("mutation", ["full_spread", "no_metal", "fresnel_normal", "no_node_scale"])
def test_random_comparison_can_fail(cl_device, mutation):
    rng = np.random.default_rng(38)
    cam = Camera(**CAMERAS["perspective"])
    mats, qs = random_case(rng, cam)
    got = run(cl_device, 1, cam, mats, qs)
    kw = {"full_spread": dict(half_spread=0.05), "no_metal": dict(metal=False),
          "fresnel_normal": dict(fresnel_at_view=False), "no_node_scale": dict(node_scale=False)}[mutation]
    ref_cam = camera_as_device(cam)
    assert compare(got, [reference(mats[q["tx"]], q, ref_cam, **kw) for q in qs])


@pytest.mark.parametrize("view", sorted(CAMERAS))
def test_normal_incidence_has_no_offset(cl_device, view):
    """A slab seen along its normal (n = v): the refracted ray goes straight on, in every channel."""
    cam = Camera(**CAMERAS[view])
    mats = [material(thickness=1.5, dispersion=1.0, ior=1.7)]
    qs = [query(px=px, py=py, z=z) for px, py, z in ((0, 0, 2.0), (160, 100, 4.0), (319, 199, 7.5), (37, 150, 1.0))]
    for vec in vec_widths(cl_device):
        for g in run(cl_device, vec, cam, mats, [dict(q) for q in qs]):
            for k in ("oxr", "oyr", "oxg", "oyg", "oxb", "oyb"):
                assert abs(g[k]) < 1e-4, (vec, k, g[k])
            assert g["lod"] == 0.0 and g["exit"] == 0.0


@pytest.mark.parametrize("dispersion", [0.0, 0.36, 2.04])
def test_tilted_plane_offset_closed_form(cl_device, dispersion):
    """Orthographic camera, n tilted by theta in the (R, -F) plane: Snell by hand per channel IOR."""
    cam = Camera(ortho=True, yaw=0.0, pitch=0.0, tan_x=3.2, tan_y=2.0)
    b = camera_as_device(cam)
    ior, d = 1.5, 0.8
    thetas = np.radians([0.0, 10.0, 30.0, 55.0, 75.0])
    mats = [material(thickness=d, ior=ior, dispersion=dispersion)]
    qs = [query(px=50 + 40 * k, py=60, z=2.0, n=np.cos(th) * (-b.F) + np.sin(th) * b.R) for k, th in enumerate(thetas)]
    got = run(cl_device, 1, cam, mats, qs)
    s = (ior - 1) * 0.025 * dispersion              # the README's half spread
    for q, g in zip(qs, got):
        th = np.arccos(np.clip(q["n"] @ (-b.F), -1, 1))
        for key, ior_c in (("oxr", ior - s), ("oxg", ior), ("oxb", ior + s)):
            tt = np.arcsin(np.sin(th) / ior_c)
            want = W / 2 * d * np.sin(th) * (np.cos(th) / ior_c - np.cos(tt)) / b.tan_x
            assert abs(g[key] - want) < 2e-4 + 2e-5 * abs(want), (np.degrees(th), key, g[key], want)
        assert abs(g["oyr"]) < 2e-4 and abs(g["oyb"]) < 2e-4
    if dispersion == 0.0:                           # no dispersion: the same bits in every channel
        for g in got:
            assert g["oxr"] == g["oxg"] == g["oxb"] and g["oyr"] == g["oyg"] == g["oyb"]
    else:                                           # R bends least, B most: offsets ordered by the IORs
        g = got[3]
        assert abs(g["oxr"]) < abs(g["oxg"]) < abs(g["oxb"])


def test_beer_lambert_node_scale_and_fresnel(cl_device):
    """A slab of thickness 0.75 × texture 0.8 × node scale 2 = 1.2 seen head-on: w_c = t base_c (1 - F0_c)
    attenuationColor_c^(1.2 / 0.6)."""
    cam = Camera(ortho=True, yaw=0.0, pitch=0.0, tan_x=3.2, tan_y=2.0)
    color, dist = (0.5, 0.25, 0.8), 0.6
    mats = [material(thickness=0.75, attenuation_distance=dist, attenuation_color=color, transmission=0.9)]
    qs = [query(tex_d=0.8, scale=2.0, c=(0.9, 0.7, 0.5))]
    g = run(cl_device, 1, cam, mats, qs)[0]
    f0 = 0.04
    for k, key in enumerate(("wr", "wg", "wb")):
        want = 0.9 * (0.9, 0.7, 0.5)[k] * (1 - f0) * color[k] ** (1.2 / dist)
        assert abs(g[key] - want) <= 1e-3 * want, (key, g[key], want)   # the 1e-3
        assert abs(g[key] - want) <= 1e-5 * want + 1e-7, (key, g[key], want)


def test_exit_faces_lod_and_thin_back_faces(cl_device):
    cam = Camera(**CAMERAS["perspective"])
    mats = [material(thickness=1.0, ior=1.25), material(thickness=0.0, ior=1.25)]
    qs = [query(tx=0, back=True, rough=0.5), query(tx=1, back=True, rough=0.5), query(tx=0, rough=0.5),
          query(tx=0, rough=0.5, a=0.0)]
    got = run(cl_device, 1, cam, mats, qs)
    assert got[0]["exit"] == 1.0 and got[0]["lod"] == -1.0 and got[0]["wr"] == got[0]["wg"] == got[0]["wb"] == 0.0
    assert got[1]["exit"] == 0.0 and got[1]["wg"] > 0.9             # thin-walled: both faces let light through
    want_lod = np.log2(320) * 0.5 * 0.5                               # applyIorToRoughness: clamp(2 * 1.25 - 2) = 0.5
    assert abs(got[1]["lod"] - want_lod) < 1e-5 and abs(got[2]["lod"] - want_lod) < 1e-5
    assert got[3]["lod"] == -1.0 and got[3]["wg"] == 0.0               # coverage 0: nothing there


# -- the texture slots through a render (transmission.h sample_tx_slot; linear data, R and G) -----------------

def constant_texture(rgba):
    from clrender import Texture
    return Texture("constant", np.tile(np.array(rgba, np.uint8), (8, 8, 1)), wrap_s="clamp", wrap_t="clamp",
                   srgb=False)


def test_transmission_and_thickness_textures_render(make_renderer, device):
    """ORTHO, face-on (N·V = 1, no offset, roughness 0: the lookup is the pixel's own opaque colour) over an
    unlit constant wall: colour - colour over a black wall (the glass's own light cancels) = T_c × the wall's
    own frame (its G-buffer colour is 8-bit),
    T_c = t c_c (1 - F0) attenuationColor_c^(d / D) with
    t = factor × R/255 of the transmission texture and d = thickness × G/255 of the thickness texture × the
    node's scale (both linear; the other channels differ so a wrong channel or an sRGB decode fails)."""
    from transmission_cases import ORTHO, QUAD_UV, SIZE, Part, assemble, glass, ortho_quad, slab, unlit
    wall_rgb = np.array([0.5, 0.7, 0.9])
    walls = [Part(ortho_quad(0, SIZE, 0, SIZE, -10.0), unlit("wall", tuple(rgb)), mesh="wall")
             for rgb in (wall_rgb, (0.0, 0.0, 0.0))]
    base = np.array([0.9, 0.6, 0.3])
    tex = [constant_texture((128, 32, 200, 77)), constant_texture((10, 64, 250, 255))]
    thin = glass(base=tuple(base), transmission=0.8, transmission_texture=0)
    vol = glass("vol", base=tuple(base), transmission=0.8, transmission_texture=0, thickness=2.0, thickness_texture=1,
                attenuation_distance=0.4, attenuation_color=(0.5, 0.8, 0.3))
    t = 0.8 * 128 / 255
    cases = {"thin": ([Part(ortho_quad(16, 48, 16, 48, -4.0), thin, uvs=QUAD_UV, mesh="pane")], 0.0),
             "volume": ([Part(p.verts, vol, uvs=QUAD_UV, mesh="slab") for p in
                         slab(ortho_quad(16, 48, 16, 48, -4.0), 0.5, vol)], 2.0 * 64 / 255 * 1.5)}
    for name, (parts, d) in cases.items():
        frame, dark = (make_renderer(SIZE, SIZE).render(assemble([w, *parts], tex, volume_scale={"slab": 1.5}), ORTHO)
                       for w in walls)
        att = np.array([0.5, 0.8, 0.3]) ** (d / 0.4) if d > 0 else np.ones(3)
        T = t * base * (1 - 0.04) * att
        inner = np.zeros((SIZE, SIZE), bool)
        inner[18:46, 18:46] = True
        bare = make_renderer(SIZE, SIZE).render(assemble([walls[0]]), ORTHO).color[inner].astype(np.float64)
        got = frame.color[inner].astype(np.float64) - dark.color[inner]
        np.testing.assert_allclose(got, T * bare, rtol=1e-5, err_msg=name)
        np.testing.assert_allclose(frame.transmittance[inner], T.mean(), rtol=2e-5, err_msg=name)
