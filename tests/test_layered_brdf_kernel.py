"""kernels/layered_brdf.h (the layered surface model of issue 37) against float64 formulas written here from the
model (KHR_materials_ior/_specular/_clearcoat/_sheen/_iridescence/_anisotropy READMEs and the Khronos Sample
Renderer where they allow an approximation), through the test kernel kernels/testing/layered_check.cl:

* layered_light with each layer on alone (specular, clearcoat, sheen, iridescence, anisotropy, diffuse transmission
  with lights in front of and behind the surface) and all together,
  on seeded random geometry and materials: rtol 1e-4 (atol 1e-6 for values near 0). Sheen cases put N.V, N.L and
  the sheen roughness on the table's nodes, where the table is exact up to its quadrature, so the reference can
  integrate E directly (the table's entries and its bilinear lookup are checked on their own).
* layered_ambient under an environment built here as arrays (the SH of an irradiance linear in the normal's y, so
  that the diffuse transmission's lookup at -N is checked, prefiltered levels whose radiance is linear in roughness
  and in the direction's v = acos(y)/pi, a DFG table linear in (N.V, roughness): bilinear lookups of linear data
  are exact, so the reflection directions R, the anisotropic bent normal's and the coat's Rcc are checked), with
  and without multiscatter, and the constant ambient; the emission scale.
* the sheen albedo table (sheen_albedo_lut) against a float64 quadrature (60 geometric N.L panels x 24
  Gauss-Legendre points, 512 azimuths): rtol 1e-4 + atol 5e-6.
* every layer degenerate: layered_light equals brdf.h's glTF BRDF (gltf_light_terms composed as compose_gltf)
  to 1e-5 at metallic 0 and 1.
Mutations of the reference (the coat's Fresnel at N instead of Ncc, no (1 - F) on the diffuse, sheen scaling by E(NV)
only, OPD at cosTheta1, the transmitted light's Fresnel at H instead of the mirrored light's, the reflected diffuse
not scaled by 1 - dt, the transmitted environment read at N) are asserted to fail the comparison. Each test runs at VEC 1 and the device's width;
the header is also built at VEC 4, 8 and 16.
"""
from __future__ import annotations

import numpy as np
import pyopencl as cl
import pytest

from clrender.device import capabilities
from clrender.device.core import Device
from clrender.passes.base import launch_1d

N_LUT = 32
LC_IN, LC_OUT = 48, 16
PI = np.pi


@pytest.fixture
def cl_device(device):
    return Device.get(device)


def vec_widths(dev: Device) -> list[int]:
    return sorted({1, capabilities.pixel_vector_width(dev.cl_device)})


# --- the model in float64 (model.md) -------------------------------------------------------------------------

def pow5(x):
    return x ** 5


def ggx_dv(alpha, nl, nh, nv):
    a2 = alpha * alpha
    d = a2 / (PI * (nh * nh * (a2 - 1) + 1) ** 2)
    return d * 0.5 / (nl * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nl * nl * (1 - a2) + a2))


def lambda_sheen(x, ag):
    o = (1 - ag) ** 2
    def h(y):
        a, b = 21.5473 * (1 - o) + 25.3245 * o, 3.82987 * (1 - o) + 3.32435 * o
        c, d, e = 0.19823 * (1 - o) + 0.16801 * o, -1.97760 * (1 - o) - 1.27393 * o, -4.32054 * (1 - o) - 4.85967 * o
        return a / (1 + b * np.maximum(y, 0) ** c) + d * y + e
    return np.where(np.abs(x) < 0.5, np.exp(h(x)), np.exp(2 * h(0.5) - h(1 - x)))


def d_charlie(shr, nh):
    ag = np.maximum(shr, 1e-6) ** 2
    return (2 + 1 / ag) * np.maximum(1 - nh * nh, 0) ** (0.5 / ag) / (2 * PI)


def v_sheen(nl, nv, shr):
    ag = np.maximum(shr, 1e-6) ** 2
    with np.errstate(divide="ignore"):
        return np.clip(1 / ((1 + lambda_sheen(nv, ag) + lambda_sheen(nl, ag)) * 4 * nv * nl), 0, 1)


def sheen_albedo(mu, shr, n_phi=512):
    """E(mu, shr) = integral of D_charlie V_sheen (N.L) over the hemisphere: Gauss-Legendre in t = N.L on
    geometric panels (and a break at 0.5, where lambdaSheen switches branches), midpoints in phi."""
    brk = np.unique(np.concatenate([[0.0, 0.5], np.geomspace(1e-7, 1, 60)]))
    x, w = np.polynomial.legendre.leggauss(24)
    t = ((brk[:-1] + brk[1:])[:, None] + (brk[1:] - brk[:-1])[:, None] * x) / 2
    wt = ((brk[1:] - brk[:-1])[:, None] * w / 2).ravel()
    t = t.ravel()[:, None]
    phi = (np.arange(n_phi) + 0.5) * PI / n_phi
    st, sv = np.sqrt(1 - t * t), np.sqrt(1 - mu * mu)
    h = np.stack([st * np.cos(phi) + sv, st * np.sin(phi), t + 0 * phi + mu])
    nh = h[2] / np.linalg.norm(h, axis=0)
    f = d_charlie(shr, nh) * v_sheen(t, mu, shr) * t
    return 2 * np.sum(f * wt[:, None]) * PI / n_phi


def sensitivity(opd, shift):
    """The README's evalSensitivity (XYZ -> Rec.709)."""
    phase = 2 * PI * opd * 1e-9
    val = np.array([5.4856e-13, 4.4201e-13, 5.2481e-13])
    pos = np.array([1.6810e6, 1.7953e6, 2.2084e6])
    var = np.array([4.3278e9, 9.3046e9, 6.6121e9])
    xyz = val * np.sqrt(2 * PI * var) * np.cos(pos * phase + shift) * np.exp(-phase ** 2 * var)
    xyz[0] += 9.7470e-14 * np.sqrt(2 * PI * 4.5282e9) * np.cos(2.2399e6 * phase + shift[0]) * np.exp(-4.5282e9 * phase ** 2)
    xyz /= 1.0685e-7
    m = np.array([[3.2404542, -1.5371385, -0.4985314], [-0.9692660, 1.8760108, 0.0415560],
                  [0.0556434, -0.2040259, 1.0572252]])
    return m @ xyz


def iridescence(cos1, eta2, d, f0, opd_cos1=False):
    """evalIridescence(outside IOR 1, eta2, cosTheta1, thickness d nm, base F0) (README + Sample Renderer)."""
    t = np.clip(d / 0.03, 0, 1)
    eta = 1 + (eta2 - 1) * t * t * (3 - 2 * t)
    cos2 = np.sqrt(1 - (1 / eta) ** 2 * (1 - cos1 ** 2))
    r0 = ((eta - 1) / (eta + 1)) ** 2
    r12 = r0 + (1 - r0) * pow5(1 - cos1)
    t121 = 1 - r12
    phi21 = PI - (PI if eta < 1 else 0.0)
    base_ior = (1 + np.sqrt(np.clip(f0, 0, 0.9999))) / (1 - np.sqrt(np.clip(f0, 0, 0.9999)))
    r1 = ((base_ior - eta) / (base_ior + eta)) ** 2
    r23 = r1 + (1 - r1) * pow5(1 - cos2)
    phi = phi21 + np.where(base_ior < eta, PI, 0.0)
    opd = 2 * eta * d * (cos1 if opd_cos1 else cos2)
    r123 = np.clip(r12 * r23, 1e-5, 0.9999)
    rs = t121 ** 2 * r23 / (1 - r123)
    i = r12 + rs
    cm = rs - t121
    for m in (1, 2):
        cm = cm * np.sqrt(r123)
        i = i + cm * 2 * sensitivity(m * opd, m * phi)
    return np.maximum(i, 0)


def prepared(p, mut=()):
    """The per-pixel derived terms of query p (a dict of float64 arrays / scalars)."""
    q = dict(p)
    n, v = p["n"], p["v"]
    t = p["at"] - n * np.dot(n, p["at"])
    q["at"] = t / np.linalg.norm(t)
    q["ab"] = np.cross(n, q["at"])
    q["nv"] = max(np.dot(n, v), 1e-4)
    q["rough"] = np.clip(p["rough"], 0, 1)
    q["alpha"] = max(q["rough"], 0.01) ** 2
    q["f0"] = np.minimum(((p["ior"] - 1) / (p["ior"] + 1)) ** 2 * p["sc"], 1)
    ncc = p["n"] if "fc_at_n" in mut else p["ncc"]
    q["fc"] = 0.04 + 0.96 * pow5(1 - np.clip(np.dot(ncc, v), 0, 1))
    q["cc_alpha"] = max(np.clip(p["cc_rough"], 0, 1), 0.01) ** 2
    q["irid"] = p["irid"] if p["thick"] > 0 else 0.0
    q["E_nv"] = sheen_albedo(q["nv"], p["sh_rough"]) if p["sh"].max() > 0 else 0.0
    if q["irid"] > 0:
        q["fid"] = iridescence(q["nv"], p["irid_ior"], p["thick"], q["f0"], "opd_cos1" in mut)
        q["fim"] = iridescence(q["nv"], p["irid_ior"], p["thick"], p["c"], "opd_cos1" in mut)
    else:
        q["fid"] = q["fim"] = np.zeros(3)
    return q


def ref_light(p, mut=()):
    q = prepared(p, mut)
    n, v, L, I, c, m, sw = q["n"], q["v"], q["L"], q["I"], q["c"], q["metallic"], q["sw"]
    h = (L + v) / np.linalg.norm(L + v)
    nl, nh, vh, nv = np.clip(n @ L, 0, 1), np.clip(n @ h, 0, 1), np.clip(v @ h, 0, 1), q["nv"]
    if q["aniso"] > 0:
        r = q["rough"]
        at, ab = (r + (1 - r) * q["aniso"] ** 2) ** 2, np.clip(r * r, 0.001, 1)
        T, B = q["at"], q["ab"]
        a2 = at * ab
        f = np.array([ab * (T @ h), at * (B @ h), a2 * nh])
        D = a2 * (a2 / (f @ f)) ** 2 / PI
        Vis = np.clip(0.5 / (nl * np.linalg.norm([at * (T @ v), ab * (B @ v), nv])
                             + nv * np.linalg.norm([at * (T @ L), ab * (B @ L), nl])), 0, 1)
        dv = D * Vis
    else:
        dv = ggx_dv(q["alpha"], nl, nh, nv)
    w = pow5(1 - vh)
    kf = (1 if "dt_front_unscaled" in mut else (1 - q["dt"])) * q["dw"]
    diffuse = I * nl * c * kf / PI
    spec = I * nl * dv
    fd = sw * q["f0"] + (sw - sw * q["f0"]) * w
    metal = (c + (1 - c) * w) * spec
    diel = diffuse * (1 - (fd if "no_diffuse_fresnel" not in mut else 0)) + spec * fd
    if q["irid"] > 0:
        metal = metal + (spec * q["fim"] - metal) * q["irid"]
        mixd = (1 - q["fid"].max()) * diffuse + q["fid"] * spec
        diel = diel + (mixd - diel) * q["irid"]
    col = diel * (1 - m) + metal * m
    shc = q["sh"]
    if shc.max() > 0:
        e_nl = sheen_albedo(nl, q["sh_rough"]) if "sheen_nv_only" not in mut else q["E_nv"]
        col = (I * nl * shc * d_charlie(q["sh_rough"], nh) * v_sheen(nl, nv, q["sh_rough"])
               + col * min(1 - shc.max() * q["E_nv"], 1 - shc.max() * e_nl))
    if q["cc"] > 0:
        ncc = q["ncc"]
        nccl, ncch, nccv = np.clip(ncc @ L, 0, 1), np.clip(ncc @ h, 0, 1), max(np.clip(ncc @ v, 0, 1), 1e-4)
        coat = I * nccl * ggx_dv(q["cc_alpha"], nccl, ncch, nccv) if nccl > 0 else 0 * I
        t = q["cc"] * q["fc"]
        col = col * (1 - t) + coat * t
    if q["dt"] > 0 and n @ L < 0:       # KHR_materials_diffuse_transmission: the diffuse BTDF from behind
        nlb = -(n @ L)
        lm = L + 2 * nlb * n                                     # the light mirrored through the surface
        hb = (lm + v) / np.linalg.norm(lm + v) if "back_fresnel_at_h" not in mut else h
        fdb = sw * q["f0"] + (sw - sw * q["f0"]) * pow5(1 - np.clip(v @ hb, 0, 1))
        btdf = I * nlb * q["dtc"] * q["dt"] * q["dw"] / PI
        back = btdf * (1 - fdb)
        if q["irid"] > 0:
            back = back + ((1 - q["fid"].max()) * btdf - back) * q["irid"]
        back = back * (1 - m)
        if shc.max() > 0:
            back = back * max(min(1 - shc.max() * q["E_nv"], 1 - shc.max() * sheen_albedo(nlb, q["sh_rough"])), 0)
        col = col + back * (1 - q["cc"] * q["fc"])
    return col, q


# --- the uniform environment (environment.h's buffers, built here) -----------------------------------------
ENV_LC = np.array([0.7, 0.9, 1.3])       # irradiance E/pi; prefiltered level at roughness r: LC (1 + 0.5 r) (1 + TILT v)
ENV_K = 6                                # specular levels
ENV_W, ENV_H, ENV_TILT = 8, 16, 0.3      # and each level's rows times 1 + TILT v (v = acos(y)/pi; linear in v)
ENV_IRR_Y = 0.4                          # the irradiance is LC (1 + IRR_Y n_y): an SH band-1 term
DFG_N = 8
DFG_A = (0.35, 0.5, -0.2)                # A = a0 + a1 clamp(nv) + a2 rough (linear: bilinear lookups are exact)
DFG_B = (0.02, -0.015, 0.06)


def env_buffers(dev: Device):
    mf = cl.mem_flags
    w, h = ENV_W, ENV_H
    texels, levels = [], []
    rows = np.repeat(1 + ENV_TILT * (np.arange(h) + 0.5) / h, w)[:, None]
    for lev in range(ENV_K + 1):
        scale = 1.0 if lev == 0 else 1 + 0.5 * (lev - 1) / (ENV_K - 1)
        levels += [lev * w * h, w, h, 0]
        texels.append(ENV_LC * scale * rows)
    sh = np.zeros(27)
    sh[:3] = ENV_LC / 0.282094791773878                  # E/pi of a constant radiance is that radiance
    sh[3:6] = ENV_LC * ENV_IRR_Y / 0.488602511902920     # Y_1 = K1 y (environment.h)
    jj, ii = np.meshgrid(np.arange(DFG_N), np.arange(DFG_N), indexing="ij")
    x, y = (ii + 0.5) / DFG_N, jj / (DFG_N - 1)
    dfg = np.stack([DFG_A[0] + DFG_A[1] * x + DFG_A[2] * y, DFG_B[0] + DFG_B[1] * x + DFG_B[2] * y,
                    np.full_like(x, 0.9)], -1)
    params = np.array([1.0, 0.0, ENV_K, DFG_N, 1.0, 0.0, ENV_K + 1, 0.0])
    arrays = [np.concatenate(texels).astype(np.float32), np.array(levels, np.int32), sh.astype(np.float32),
              dfg.astype(np.float32), params.astype(np.float32)]
    return [cl.Buffer(dev.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a) for a in arrays]


def ref_ambient(p, has_env, ambient, multiscatter, mut=()):
    q = prepared(p, mut)
    c, m, sw, r, nv = q["c"], q["metallic"], q["sw"], q["rough"], q["nv"]
    shm, E = q["sh"].max(), q["E_nv"]
    occ = q["ao"] * q["occ"]
    dt, dw = q["dt"], q["dw"]
    if not has_env:
        albedo = (c * (1 - dt) + q["dtc"] * dt) * dw               # both sides lit by the constant ambient
        return (ambient * occ * albedo * (1 - m) * (1 - (sw * q["f0"] * (1 - m) + c * m)) * (1 - shm * E)
                * (1 - q["cc"] * q["fc"]))
    xc = np.clip(nv, 0.5 / DFG_N, 1 - 0.5 / DFG_N)
    A, B = DFG_A[0] + DFG_A[1] * xc + DFG_A[2] * r, DFG_B[0] + DFG_B[1] * xc + DFG_B[2] * r

    def fss(f0, w):
        ks = f0 + (np.maximum(1 - r, f0) - f0) * pow5(1 - nv)
        f = w * (ks * A + B)
        if multiscatter:
            ems, favg = 1 - (A + B), w * (f0 + (1 - f0) / 21)
            f = f + ems * f * favg / (1 - favg * ems)
        return f

    def pref(rough, nrm):
        """The prefiltered radiance along R = reflect(-V, nrm): linear in the direction's v, clamped at the
        first and last rows' centres."""
        R = 2 * (nrm @ q["v"]) * nrm - q["v"]
        vv = np.clip(np.arccos(np.clip(R[1] / np.linalg.norm(R), -1, 1)) / PI, 0.5 / ENV_H, 1 - 0.5 / ENV_H)
        return ENV_LC * (1 + 0.5 * np.clip(rough, 0, 1)) * (1 + ENV_TILT * vv)

    nb = q["n"]
    if q["aniso"] > 0 and "no_bent_normal" not in mut:     # ibl.glsl's bent normal, anisotropyDirection = Ab
        an = np.cross(np.cross(q["ab"], q["v"]), q["ab"])
        bend = (1 - q["aniso"] * (1 - r)) ** 4
        nb = an * (1 - bend) + q["n"] * bend
        nb = nb / np.linalg.norm(nb)
    p_r = pref(r, nb)

    def irradiance(nrm):
        return ENV_LC * (1 + ENV_IRR_Y * nrm[1])
    far = q["n"] if "dt_env_front" in mut else -q["n"]            # the light through the surface: from behind
    f_diffuse = (irradiance(q["n"]) * c * (1 - dt) + irradiance(far) * q["dtc"] * dt) * dw
    f_metal = fss(c, 1.0) * p_r
    f_diel = f_diffuse * (1 - fss(q["f0"], sw)) + p_r * fss(q["f0"], sw)
    if q["irid"] > 0:
        f_metal = f_metal + (p_r * q["fim"] - f_metal) * q["irid"]
        f_diel = f_diel + ((1 - q["fid"].max()) * f_diffuse + q["fid"] * p_r - f_diel) * q["irid"]
    col = f_diel * (1 - m) + f_metal * m
    if shm > 0:
        col = pref(q["sh_rough"], nb) * q["sh"] * E + col * (1 - shm * E)
    if q["cc"] > 0:
        t = q["cc"] * q["fc"]
        col = col * (1 - t) + pref(q["cc_rough"], q["ncc"]) * t
    return col * occ


# --- queries and the device ------------------------------------------------------------------------------------
KEYS = (("n", 3), ("ng", 3), ("ncc", 3), ("at", 3), ("v", 3), ("c", 3), ("metallic", 1), ("rough", 1), ("ior", 1),
        ("sw", 1), ("sc", 3), ("cc", 1), ("cc_rough", 1), ("sh", 3), ("sh_rough", 1), ("irid", 1), ("irid_ior", 1),
        ("thick", 1), ("aniso", 1), ("L", 3), ("I", 3), ("ao", 1), ("occ", 1), ("dt", 1), ("dtc", 3), ("dw", 1))


def unit(x):
    x = np.asarray(x, np.float64)
    return x / np.linalg.norm(x)


def around(n, cos, rng):
    """A unit vector at angle acos(cos) from n, random azimuth."""
    e1 = unit(np.cross(n, [0.3, 1.0, 0.2]))
    e2 = np.cross(n, e1)
    a = rng.uniform(0, 2 * PI)
    return cos * n + np.sqrt(1 - cos * cos) * (np.cos(a) * e1 + np.sin(a) * e2)


def base_query(rng, metallic=None):
    n = unit(rng.normal(size=3))
    return dict(n=n, ng=unit(n + 0.2 * rng.normal(size=3)), ncc=n, at=unit(rng.normal(size=3)),
                v=around(n, rng.uniform(0.15, 0.95), rng), c=rng.uniform(0.05, 0.95, 3),
                metallic=rng.choice([0.0, 1.0, rng.uniform()]) if metallic is None else metallic,
                rough=rng.uniform(0.3, 1.0), ior=1.5, sw=1.0, sc=np.ones(3), cc=0.0, cc_rough=0.0, sh=np.zeros(3),
                sh_rough=0.0, irid=0.0, irid_ior=1.3, thick=0.0, aniso=0.0, L=around(n, rng.uniform(0.1, 0.95), rng),
                I=rng.uniform(0.5, 3.0, 3), ao=rng.uniform(0.5, 1.0), occ=rng.uniform(0.5, 1.0), dt=0.0, dtc=np.ones(3),
                dw=1.0)


def with_layer(q, layer, rng):
    if layer in ("specular", "all"):
        q.update(ior=rng.choice([0.0, rng.uniform(1.1, 2.5)]), sw=rng.uniform(0.2, 1.0), sc=rng.uniform(0.3, 1.5, 3))
    if layer in ("clearcoat", "all"):
        q.update(cc=rng.uniform(0.3, 1.0), cc_rough=rng.uniform(0.2, 0.8), ncc=unit(q["n"] + 0.3 * rng.normal(size=3)))
    if layer in ("sheen", "all"):       # N.V, N.L and the roughness on the table's nodes (module doc)
        i, j, k = rng.integers(2, N_LUT - 1), rng.integers(2, N_LUT - 1), rng.integers(5, N_LUT)
        q.update(v=around(q["n"], (i + 0.5) / N_LUT, rng), L=around(q["n"], (j + 0.5) / N_LUT, rng),
                 sh=rng.uniform(0.2, 1.0, 3), sh_rough=(k + 0.5) / N_LUT)
    if layer in ("iridescence", "all"):
        q.update(irid=rng.uniform(0.3, 1.0), irid_ior=rng.uniform(1.2, 2.0), thick=rng.uniform(100, 800))
    if layer in ("anisotropy", "all"):
        q.update(aniso=rng.uniform(0.2, 1.0))
    if layer.startswith("dt_") or layer == "diffuse_transmission":
        q = with_layer(q, "all", rng) if layer == "dt_all" else q      # every layer: N.L, N.V on the sheen nodes
        q.update(dt=rng.uniform(0.2, 1.0), dtc=rng.uniform(0.1, 1.0, 3), dw=rng.choice([1.0, rng.uniform(0.3, 1.0)]))
        side = {"dt_back": -1, "dt_front": 1}.get(layer, rng.choice([-1, 1]))
        if side * (q["n"] @ q["L"]) < 0:                                   # mirrored through the surface
            q["L"] = q["L"] - 2 * (q["n"] @ q["L"]) * q["n"]
    return q


def pack(qs) -> np.ndarray:
    """The queries as layered_check.cl reads them; the dicts get the float32-rounded values (the reference
    sees what the device sees)."""
    a = np.zeros((len(qs), LC_IN), np.float32)
    for r, q in enumerate(qs):
        at = 0
        for key, size in KEYS:
            a[r, at: at + size] = q[key]
            q[key] = a[r, at: at + size].astype(np.float64) if size == 3 else float(a[r, at])
            at += size
    return a


_LUTS: dict = {}             # (device, VEC) -> the device's sheen table (one computation per session)


class Probe:
    def __init__(self, dev: Device, vec: int):
        self.dev, self.vec = dev, vec
        self.kernel = dev.kernel("testing/layered_check.cl", "layered_check", {"VEC": vec})
        key = (id(dev), vec)
        if key not in _LUTS:
            _LUTS[key] = sheen_lut(dev, vec)
        self.lut = _LUTS[key]
        mf = cl.mem_flags
        self.lut_buf = cl.Buffer(dev.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=self.lut)
        self.env = env_buffers(dev)

    def __call__(self, qs, has_env=0, ambient=0.0, multiscatter=0) -> np.ndarray:
        dev, mf = self.dev, cl.mem_flags
        a = pack(qs)
        qbuf = cl.Buffer(dev.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)
        out = np.zeros((len(qs), LC_OUT), np.float32)
        obuf = cl.Buffer(dev.context, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=out)
        g, l = launch_1d(-(-len(qs) // self.vec))
        self.kernel(dev.queue, g, l, *self.env, self.lut_buf, qbuf, np.int32(len(qs)), np.int32(has_env),
                    np.float32(ambient), np.int32(multiscatter), obuf)
        cl.enqueue_copy(dev.queue, out, obuf)
        return out.astype(np.float64)


def sheen_lut(dev: Device, vec: int = 1) -> np.ndarray:
    k = dev.kernel("testing/layered_check.cl", "sheen_albedo_lut", {"VEC": vec})
    lut = np.zeros(N_LUT * N_LUT, np.float32)
    buf = cl.Buffer(dev.context, cl.mem_flags.WRITE_ONLY, lut.nbytes)
    g, l = launch_1d(N_LUT * N_LUT)
    k(dev.queue, g, l, buf)
    cl.enqueue_copy(dev.queue, lut, buf)
    return lut


def bad(got, want, rtol=1e-4, atol=1e-6):
    """Mask of the values outside |got - want| <= rtol |want| + atol."""
    return np.abs(got - want) > rtol * np.abs(want) + atol


# --- tests ------------------------------------------------------------------------------------------------------
LAYERS = ("specular", "clearcoat", "sheen", "iridescence", "anisotropy", "all", "diffuse_transmission", "dt_all")


@pytest.mark.parametrize("layer", LAYERS)
def test_light_each_layer_matches_float64_model(cl_device, layer):
    rng = np.random.default_rng(100 + LAYERS.index(layer))
    qs = [with_layer(base_query(rng), layer, rng) for _ in range(12)]
    if layer not in ("sheen", "all", "dt_all"):
        qs[0]["L"] = around(qs[0]["n"], -0.3, rng)           # behind the base: 0, the coat alone, or transmitted
    for vec in vec_widths(cl_device):
        got = Probe(cl_device, vec)(qs)[:, 0:3]
        want = np.array([ref_light(q)[0] for q in qs])
        assert not bad(got, want).any(), f"VEC {vec} {layer}: max rel err {np.max(np.abs(got - want) / (np.abs(want) + 1e-6)):.2e}"
        assert (want > 1e-3).all() or layer not in ("sheen",)
    if layer == "iridescence":
        out = Probe(cl_device, 1)(qs)
        want_fi = np.array([np.concatenate([prepared(q)["fid"], prepared(q)["fim"]]) for q in qs])
        assert not bad(out[:, 10:16], want_fi).any()


@pytest.mark.parametrize("mutation, layer", [("fc_at_n", "clearcoat"), ("no_diffuse_fresnel", "specular"),
                                             ("sheen_nv_only", "sheen"), ("opd_cos1", "iridescence"),
                                             ("back_fresnel_at_h", "dt_back"), ("dt_front_unscaled", "dt_front")])
def test_light_comparison_can_fail(cl_device, mutation, layer):
    rng = np.random.default_rng(7)
    qs = [with_layer(base_query(rng, metallic=0.0), layer, rng) for _ in range(12)]
    got = Probe(cl_device, 1)(qs)[:, 0:3]
    want = np.array([ref_light(q, (mutation,))[0] for q in qs])
    assert bad(got, want).mean() > 0.3, mutation


@pytest.mark.parametrize("has_env, multiscatter", [(1, 0), (1, 1), (0, 0)])
def test_ambient_and_emission_match_float64_model(cl_device, has_env, multiscatter):
    rng = np.random.default_rng(200 + 2 * has_env + multiscatter)
    qs = [with_layer(base_query(rng), layer, rng) for layer in LAYERS for _ in range(3)]
    for vec in vec_widths(cl_device):
        out = Probe(cl_device, vec)(qs, has_env=has_env, ambient=0.37, multiscatter=multiscatter)
        want = np.array([ref_ambient(q, has_env, 0.37, multiscatter) for q in qs])
        assert not bad(out[:, 3:6], want).any(), f"VEC {vec}: max abs err {np.max(np.abs(out[:, 3:6] - want)):.2e}"
        emission = np.array([1 - q["cc"] * prepared(q)["fc"] for q in qs])
        assert not bad(out[:, 6], emission, 1e-5).any()
    if has_env:     # the reference with the coat's Fresnel at N instead of Ncc must fail
        for mutation, key in (("fc_at_n", "cc"), ("no_bent_normal", "aniso"), ("dt_env_front", "dt")):
            want = np.array([ref_ambient(q, has_env, 0.37, multiscatter, (mutation,)) for q in qs])
            # (the irradiance at -N differs from N's where N is not horizontal, and a metal has no diffuse)
            sel = [i for i, q in enumerate(qs) if q[key] > 0 and (key != "dt" or (q["metallic"] < 0.9
                                                                               and abs(q["n"][1]) > 0.2))]
            assert len(sel) >= 2 and bad(out[:, 3:6], want)[sel].all(axis=1).mean() > 0.5, mutation


def test_sheen_table_matches_float64_quadrature(cl_device):
    rng = np.random.default_rng(5)
    picks = {(0, 0), (N_LUT - 1, N_LUT - 1), (0, N_LUT - 1), (N_LUT - 1, 0), (0, 6), (3, 31)}
    picks |= {tuple(int(x) for x in rng.integers(0, N_LUT, 2)) for _ in range(18)}
    for vec in vec_widths(cl_device):
        lut = sheen_lut(cl_device, vec).reshape(N_LUT, N_LUT)      # [rough j, mu i]
        for i, j in sorted(picks):
            want = sheen_albedo((i + 0.5) / N_LUT, (j + 0.5) / N_LUT)
            assert abs(lut[j, i] - want) <= 1e-4 * want + 5e-6, (i, j, lut[j, i], want)
    # the lookup between the nodes: bilinear in the device's own table
    qs = [with_layer(base_query(rng), "sheen", rng) for _ in range(8)]
    for q in qs:
        q["v"] = around(q["n"], rng.uniform(0.01, 0.99), rng)
        q["sh_rough"] = rng.uniform(0.0, 1.0)
    out = Probe(cl_device, 1)(qs, has_env=0, ambient=1.0)
    lut = sheen_lut(cl_device).reshape(N_LUT, N_LUT).astype(np.float64)
    for q, o in zip(qs, out):
        fx = np.clip(q["n"] @ q["v"] * N_LUT - 0.5, 0, N_LUT - 1)
        fy = np.clip(q["sh_rough"] * N_LUT - 0.5, 0, N_LUT - 1)
        x0, y0 = int(fx), int(fy)
        x1, y1 = min(x0 + 1, N_LUT - 1), min(y0 + 1, N_LUT - 1)
        ax, ay = fx - x0, fy - y0
        e = (lut[y0, x0] * (1 - ax) + lut[y0, x1] * ax) * (1 - ay) + (lut[y1, x0] * (1 - ax) + lut[y1, x1] * ax) * ay
        p = prepared(dict(q, sh=np.zeros(3)))
        want = (0.37 / 0.37) * q["ao"] * q["occ"] * q["c"] * (1 - q["metallic"]) \
            * (1 - (q["sw"] * p["f0"] * (1 - q["metallic"]) + q["c"] * q["metallic"])) * (1 - q["sh"].max() * e)
        assert not bad(o[3:6], want).any()


@pytest.mark.parametrize("metallic", [0.0, 1.0])
def test_degenerate_layers_equal_base_gltf_brdf(cl_device, metallic):
    rng = np.random.default_rng(300 + int(metallic))
    qs = [base_query(rng, metallic=metallic) for _ in range(40)]
    qs[0]["L"] = around(qs[0]["n"], -0.2, rng)
    for vec in vec_widths(cl_device):
        out = Probe(cl_device, vec)(qs)
        assert not bad(out[:, 0:3], out[:, 7:10], 1e-5, 1e-7).any(), f"VEC {vec}"
        assert (out[1:, 0:3] > 0).all() and (out[0, 0:3] == 0).all()


@pytest.mark.parametrize("vec", [4, 8, 16])
def test_header_builds_at_every_width(cl_device, vec):
    cl_device.kernel("testing/layered_check.cl", "layered_check", {"VEC": vec}).resolve()
