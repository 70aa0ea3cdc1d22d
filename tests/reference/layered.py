"""Independent NumPy (float64) reference of the layered glTF surface model of issues 37 and 38: shade_layered() per pixel
on arrays of N pixels, returning linear RGB (N, 3). The pieces (Fresnel, GGX, anisotropic GGX, Charlie sheen and
its albedo, the thin film, the split-sum terms) are in layered_pieces.py, re-exported here; its doc lists the
sources and the choices where the READMEs and the lead's model note differ.

Per pixel (the note; x = V.H, NL, NH, VH, NccL, NccH clamped to [0, 1], NV = max(N.V, 1e-4), alpha = max(r, 0.01)^2,
f0_d = min(f0_from_ior(ior) sc, 1), F_d = Schlick(sw f0_d, sw), F_m = Schlick(c, 1), Fc = 0.04 + 0.96 (1 -
clamp01(Ncc.V))^5, Fi_d / Fi_m = eval_iridescence(1, irid_ior, NV, d, f0_d / c), irid = 0 where d = 0,
E = sheen_albedo):
  per light (I, L): diffuse = I NL c / pi; spec = I NL D Vis (anisotropic D, V with At, Ab where aniso > 0);
    metal = F_m spec; diel = diffuse (1 - F_d) + spec F_d; iridescence mixes in spec Fi_m and
    rgb_mix(diffuse, spec, Fi_d) by irid; col = mix(diel, metal, m); sheen: I NL shc D_charlie V_sheen +
    col min(1 - max3(shc) E(NV), 1 - max3(shc) E(NL)); clearcoat: mix(col, I NccL D Vis (alpha_cc, on Ncc), cc Fc).
  environment: the same with f_diffuse = irradiance(N) c, pref(R, r), FssEss(F0, w) for the Fresnel terms
    (bent normal in R where aniso > 0), sheen pref(R, shr) shc E(NV) + col (1 - max3(shc) E(NV)), clearcoat
    mix(col, pref(Rcc, ccr), cc Fc); times occ ao.
  no environment: a occ ao c (1 - m)(1 - mix(sw f0_d, c, m))(1 - max3(shc) E(NV))(1 - cc Fc).
  emission e (1 - cc Fc).
Diffuse transmission (KHR_materials_diffuse_transmission README, "Implementation": the dielectric's base is
mix(diffuse_brdf(c), diffuse_btdf(dtc), dt), the brdf for light and view on the same side, the btdf for opposite
sides; with KHR_materials_transmission that diffuse BSDF is weighted by dw = 1 - transmission; dt, dtc, dw below):
  the reflected diffuse albedo is c (1 - dt) dw; a light on the far side (N.L < 0) is the same model evaluated with
  no specular, sheen or coat lobe, the albedo dtc dt dw, the cosine -N.L, and the Fresnel, sheen-albedo and
  iridescence terms at the light mirrored through the surface, L - 2 (N.L) N (where the Sample Renderer evaluates
  them); the environment's diffuse is irradiance(N) c (1 - dt) dw + irradiance(-N) dtc dt dw (the light through
  the surface comes from the other hemisphere), the constant ambient's albedo (c (1 - dt) + dtc dt) dw.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .brdf_reference import MIN_ROUGHNESS, punctual_attenuation
from .ibl_reference import brute_irradiance, ggx_prefilter
from .layered_pieces import (DIFFERENCES, NV_MIN, SHEEN_MIN_ROUGHNESS, _c01, _dot, _max3, _mix,
                             _sheen_albedo_cached, _unit, aniso_alphas, d_charlie, d_ggx, d_ggx_aniso, dfg,
                             eval_iridescence, eval_sensitivity, f0_from_ior, fresnel_schlick, fss_ess,
                             lambda_sheen, rgb_mix, sheen_albedo, thin_film_terms, vis_ggx, vis_ggx_aniso, vis_sheen)

__all__ = ["DIFFERENCES", "NV_MIN", "SHEEN_MIN_ROUGHNESS", "Environment", "Surface", "SURFACE_DEFAULTS",
           "aniso_alphas", "coat_normal", "d_charlie", "d_ggx", "d_ggx_aniso", "dfg", "eval_iridescence",
           "eval_sensitivity", "f0_from_ior", "fresnel_schlick", "fss_ess", "lambda_sheen", "light_inputs",
           "make_surface", "rgb_mix", "shade_environment", "shade_layered", "shade_light", "shade_transmitted",
           "sheen_albedo", "tangent_frame", "thin_film_terms", "vis_ggx", "vis_ggx_aniso", "vis_sheen"]


# -- inputs ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Environment:
    """Image-based light: irradiance(n (K, 3)) -> E(n)/pi (K, 3) (radiance units, what the albedo multiplies);
    prefiltered(R (K, 3), rough (K,)) -> (K, 3) GGX-prefiltered radiance (N = V = R). Any callables (e.g. an
    SH irradiance); uniform() and equirect() build the usual two."""
    irradiance: Callable
    prefiltered: Callable

    @staticmethod
    def uniform(rgb) -> "Environment":
        """A constant radiance: every lookup is rgb."""
        c = np.asarray(rgb, np.float64).reshape(3)

        def const(d, *_):
            return np.broadcast_to(c, np.shape(d)[:-1] + (3,)).copy()
        return Environment(const, const)

    @staticmethod
    def equirect(pixels, rotation_deg=0.0) -> "Environment":
        """An equirectangular radiance image (h, w, 3) in environment.h's convention (ibl_reference.dir_uv):
        brute-force irradiance and GGX prefilter by texel sums (ibl_reference), roughness >= 0.01."""
        img = np.asarray(pixels, np.float64)
        ca, sa = np.cos(np.radians(rotation_deg)), np.sin(np.radians(rotation_deg))

        def rot(d):             # the texel direction a lookup of d reads: phi + rotation about +Y
            d = _unit(np.asarray(d, np.float64))
            return np.stack([d[..., 0] * ca - d[..., 2] * sa, d[..., 1], d[..., 2] * ca + d[..., 0] * sa], -1)

        def pref(R, rough):
            R = rot(R)
            rough = np.broadcast_to(np.maximum(rough, MIN_ROUGHNESS), R.shape[:-1])
            out = np.empty(R.shape)
            for v in np.unique(rough):
                out[rough == v] = ggx_prefilter(img, R[rough == v], float(v))
            return out
        return Environment(lambda n: brute_irradiance(img, rot(n)), pref)


VEC3 = ("c", "N", "V", "Ng", "T", "Bt", "P", "e", "sc", "Ncc", "shc", "dtc")
SCALARS = ("m", "r", "occ", "ior", "sw", "cc", "ccr", "shr", "irid", "d", "irid_ior", "aniso", "aniso_rot", "dt", "dw")


@dataclass(frozen=True)
class Surface:
    """Per-pixel inputs of the note, arrays over N pixels: (N, 3) c, N, V, Ng, T, Bt, P, e, sc, Ncc, shc;
    (N,) m, r, occ, ior, sw, cc, ccr, shr, irid, d (nm), irid_ior, aniso (strength), aniso_rot (radians);
    (N, 2) aniso_dir (tangent-space direction before the rotation); (N,) dt (diffuse transmission), (N, 3) dtc
    (its colour), (N,) dw (the diffuse BSDF's weight, 1 - transmission). T, Bt, P may be None. Build with
    make_surface()."""
    c: np.ndarray
    m: np.ndarray
    r: np.ndarray
    N: np.ndarray
    V: np.ndarray
    Ng: np.ndarray
    T: np.ndarray | None
    Bt: np.ndarray | None
    P: np.ndarray | None
    occ: np.ndarray
    e: np.ndarray
    ior: np.ndarray
    sw: np.ndarray
    sc: np.ndarray
    cc: np.ndarray
    ccr: np.ndarray
    Ncc: np.ndarray
    shc: np.ndarray
    shr: np.ndarray
    irid: np.ndarray
    d: np.ndarray
    irid_ior: np.ndarray
    aniso: np.ndarray
    aniso_dir: np.ndarray
    aniso_rot: np.ndarray
    dt: np.ndarray
    dtc: np.ndarray
    dw: np.ndarray


SURFACE_DEFAULTS = dict(occ=1.0, e=0.0, ior=1.5, sw=1.0, sc=1.0, cc=0.0, ccr=0.0, shc=0.0, shr=0.0, irid=0.0,
                        d=400.0, irid_ior=1.3, aniso=0.0, aniso_dir=(1.0, 0.0), aniso_rot=0.0, dt=0.0, dtc=1.0,
                        dw=1.0)


def tangent_frame(Ng, tangent, handedness=1.0):
    """The note's T, Bt: the vertex tangent made orthogonal to Ng and normalized, Bt = cross(Ng, T) h."""
    Ng, t = np.asarray(Ng, np.float64), np.asarray(tangent, np.float64)
    T = _unit(t - _dot(t, Ng)[..., None] * Ng)
    return T, np.cross(Ng, T) * np.asarray(handedness, np.float64)[..., None]


def coat_normal(T, Bt, Ng, tex_rgb, scale=1.0):
    """The note's Ncc from a clearcoat normal texel: normalize(T x + Bt y + Ng z), (x, y, z) =
    normalize(2 rgb - 1 with x, y times the scale)."""
    t = 2.0 * np.asarray(tex_rgb, np.float64) - 1.0
    t = _unit(t * np.array([scale, scale, 1.0]))
    return _unit(T * t[..., :1] + Bt * t[..., 1:2] + Ng * t[..., 2:])


def make_surface(*, c, m, r, N, V, Ng=None, T=None, Bt=None, handedness=1.0, P=None, **layer) -> Surface:
    """A Surface with every value broadcast to the N pixels of `N`; layer parameters default to "extension
    absent" (SURFACE_DEFAULTS). N, V, Ng, Ncc are normalized; r, ccr and aniso clamped to [0, 1] (the note);
    Bt = cross(Ng, T) handedness when T is given without Bt; Ncc defaults to Ng (the coat ignores the base
    normal map)."""
    unknown = set(layer) - set(SURFACE_DEFAULTS) - {"Ncc"}
    if unknown:
        raise TypeError(f"make_surface: unknown surface parameter(s) {sorted(unknown)}")
    N = _unit(np.asarray(N, np.float64))
    n = len(N)
    Ng = N if Ng is None else _unit(np.broadcast_to(np.asarray(Ng, np.float64), (n, 3)))
    vals = dict(SURFACE_DEFAULTS, **layer)
    vals.update(c=c, m=m, r=r, N=N, V=V, Ng=Ng, P=P)
    vals["Ncc"] = Ng if layer.get("Ncc") is None else layer["Ncc"]
    if T is not None:
        T = np.broadcast_to(np.asarray(T, np.float64), (n, 3))
        Bt = np.cross(Ng, T) * np.broadcast_to(np.asarray(handedness, np.float64), (n,))[:, None] if Bt is None else Bt
    vals.update(T=T, Bt=Bt)
    out = {}
    for k, v in vals.items():
        if v is None:
            out[k] = None
        elif k in VEC3:
            out[k] = np.broadcast_to(np.asarray(v, np.float64), (n, 3)).copy()
        elif k == "aniso_dir":
            out[k] = np.broadcast_to(np.asarray(v, np.float64), (n, 2)).copy()
        else:
            out[k] = np.broadcast_to(np.asarray(v, np.float64), (n,)).copy()
    for k in ("V", "Ncc"):
        out[k] = _unit(out[k])
    for k in ("r", "ccr", "aniso", "dt"):
        out[k] = _c01(out[k])
    if out["T"] is None and np.any(out["aniso"] > 0):
        raise ValueError("make_surface: anisotropy > 0 needs the tangent T")
    return Surface(**out)


def light_inputs(light, s: Surface):
    """(L (N, 3) unit towards the light, I (N, 3) rgb intensity reaching the point) of one light dict:
    {'L', 'I'} given per pixel; {'type': 'sun', 'direction' (travel), 'color'} (A = 1, colour = irradiance);
    {'type': 'point' | 'spot', 'position', 'color', 'radius' (default inf), 'falloff' (lighting.h's 0, 1, 2;
    default 2: 1/d^2), spots 'direction' (the axis), 'cos_inner', 'cos_outer'} through
    brdf_reference.punctual_attenuation (lighting.h's falloffs). Optional 'visibility' (N,) multiplies I."""
    n = len(s.N)
    if "L" in light:
        L = _unit(np.broadcast_to(np.asarray(light["L"], np.float64), (n, 3)))
        I = np.broadcast_to(np.asarray(light["I"], np.float64), (n, 3))
    elif light["type"] == "sun":
        L = np.broadcast_to(-_unit(np.asarray(light["direction"], np.float64)), (n, 3))
        I = np.broadcast_to(np.asarray(light["color"], np.float64), (n, 3))
    elif light["type"] in ("point", "spot"):
        if s.P is None:
            raise ValueError("light_inputs: point and spot lights need the positions P")
        axis = _unit(np.asarray(light.get("direction", (0.0, 0.0, -1.0)), np.float64))
        rec = dict(position=light["position"], radius=light.get("radius", np.inf), falloff=light.get("falloff", 2),
                   type=1 if light["type"] == "spot" else 0, direction=axis,
                   cos_inner=light.get("cos_inner", 1.0), cos_outer=light.get("cos_outer", 0.0))
        A, L, _ = punctual_attenuation(s.P, rec)
        I = A[:, None] * np.asarray(light["color"], np.float64)
    else:
        raise ValueError(f"light_inputs: unknown light type {light.get('type')!r}")
    return L, I * np.broadcast_to(np.asarray(light.get("visibility", 1.0), np.float64), (n,))[:, None]


# -- shading -----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Derived:
    alpha: np.ndarray
    nv: np.ndarray
    f0d: np.ndarray             # (N, 3) min(f0_ior sc, 1), before the weight sw
    Fc: np.ndarray
    nccv: np.ndarray
    alpha_cc: np.ndarray
    irid: np.ndarray            # 0 where d = 0
    Fi_d: np.ndarray
    Fi_m: np.ndarray
    Ev: np.ndarray              # E(NV, shr), 0 where shc = 0 (it is only used times max3(shc))
    At: np.ndarray | None
    Ab: np.ndarray | None


def _derive(s: Surface, opd_cos, f0_guard) -> _Derived:
    nv = np.maximum(_dot(s.N, s.V), NV_MIN)
    f0d = np.minimum(f0_from_ior(s.ior)[:, None] * s.sc, 1.0)
    nccv_raw = _c01(_dot(s.Ncc, s.V))
    irid = np.where(s.d > 0, s.irid, 0.0)
    Fi_d = eval_iridescence(1.0, s.irid_ior, nv, s.d, f0d, opd_cos, f0_guard)
    Fi_m = eval_iridescence(1.0, s.irid_ior, nv, s.d, s.c, opd_cos, f0_guard)
    sheen = _max3(s.shc) > 0
    Ev = np.zeros(len(nv))
    if sheen.any():
        Ev[sheen] = _sheen_albedo_cached(nv[sheen], s.shr[sheen])
    At = Ab = None
    if s.T is not None and np.any(s.aniso > 0):
        dr = _unit(s.aniso_dir)
        cr, sr = np.cos(s.aniso_rot), np.sin(s.aniso_rot)
        x, y = dr[:, 0] * cr - dr[:, 1] * sr, dr[:, 0] * sr + dr[:, 1] * cr        # counter-clockwise
        At = _unit(s.T * x[:, None] + s.Bt * y[:, None])
        At = _unit(At - _dot(At, s.N)[:, None] * s.N)                                # Gram-Schmidt against N
        Ab = np.cross(s.N, At)
    return _Derived(np.maximum(s.r, MIN_ROUGHNESS) ** 2, nv, f0d, 0.04 + 0.96 * (1.0 - nccv_raw) ** 5,
                    np.maximum(nccv_raw, NV_MIN), np.maximum(s.ccr, MIN_ROUGHNESS) ** 2, irid, Fi_d, Fi_m, Ev, At, Ab)


def _dielectric(diffuse, spec, F, spec_base):
    if spec_base == "rgb":
        return diffuse * (1.0 - F) + spec * F
    if spec_base == "max3":
        return rgb_mix(diffuse, spec, F)
    raise ValueError(f"spec_base {spec_base!r}: expected 'rgb' or 'max3'")


def _sheen_scale(s: Surface, dv: _Derived, nl):
    """min(1 - max3(shc) E(NV), 1 - max3(shc) E(NL)), clamped at 0 (E > 1 at grazing angles)."""
    msh = _max3(s.shc)
    El = np.zeros(len(nl))
    sel = (msh > 0) & (nl > 0)
    if sel.any():
        El[sel] = _sheen_albedo_cached(nl[sel], s.shr[sel])
    return np.maximum(np.minimum(1.0 - msh * dv.Ev, 1.0 - msh * El), 0.0)


def shade_transmitted(s: Surface, dv: _Derived, L, I, spec_base="rgb"):
    """The light of unit L (N, 3), intensity I (N, 3), reaching the far side of the surface (N.L < 0) and leaving
    towards V through the diffuse BTDF: diffuse_btdf(dtc) = dtc / pi weighted dt dw, cosine |N.L|, in the
    dielectric's Fresnel mix (no specular layer for it) at the mirrored light, then the metal's share (none), the
    iridescence, sheen and coat weights as for the diffuse reflection."""
    nlb = _c01(-_dot(s.N, L))
    Lm = L - 2.0 * _dot(s.N, L)[:, None] * s.N                       # the light mirrored through the surface
    vh = _c01(_dot(s.V, _unit(Lm + s.V)))
    btdf = I * nlb[:, None] * s.dtc * (s.dt * s.dw)[:, None] / np.pi
    sw = s.sw[:, None]
    zero = np.zeros_like(btdf)
    diel = _dielectric(btdf, zero, fresnel_schlick(sw * dv.f0d, sw, vh[:, None]), spec_base)
    diel = _mix(diel, rgb_mix(btdf, zero, dv.Fi_d), dv.irid[:, None])
    col = _mix(diel, zero, s.m[:, None]) * _sheen_scale(s, dv, nlb)[:, None]
    return _mix(col, zero, (s.cc * dv.Fc)[:, None])


def shade_light(s: Surface, dv: _Derived, L, I, spec_base="rgb", aniso="model"):
    """One punctual light's outgoing radiance (N, 3) for unit L (N, 3) and intensity I (N, 3): reflected, plus
    what diffuse transmission lets through from the far side."""
    out = _shade_reflected(s, dv, L, I, spec_base, aniso)
    return out + shade_transmitted(s, dv, L, I, spec_base) if np.any(s.dt > 0) else out


def _shade_reflected(s: Surface, dv: _Derived, L, I, spec_base="rgb", aniso="model"):
    N, V, c = s.N, s.V, s.c
    nl = _c01(_dot(N, L))
    h = L + V
    hn = np.linalg.norm(h, axis=-1, keepdims=True)
    H = np.where(hn > 0, h / np.where(hn > 0, hn, 1.0), N)
    nh, vh = _c01(_dot(N, H)), _c01(_dot(V, H))
    lobe = d_ggx(nh, dv.alpha) * vis_ggx(nl, dv.nv, dv.alpha)
    if dv.At is not None:
        at, ab = aniso_alphas(s.r, s.aniso, aniso)
        At, Ab = dv.At, dv.Ab
        la = d_ggx_aniso(nh, _dot(At, H), _dot(Ab, H), at, ab) * vis_ggx_aniso(
            nl, dv.nv, _dot(At, V), _dot(Ab, V), _dot(At, L), _dot(Ab, L), at, ab)
        lobe = np.where(s.aniso > 0, la, lobe)
    k = I * nl[:, None]
    diffuse, spec = k * (c * ((1.0 - s.dt) * s.dw)[:, None]) / np.pi, k * lobe[:, None]
    sw = s.sw[:, None]
    metal = fresnel_schlick(c, 1.0, vh[:, None]) * spec
    diel = _dielectric(diffuse, spec, fresnel_schlick(sw * dv.f0d, sw, vh[:, None]), spec_base)
    ir = dv.irid[:, None]
    metal = _mix(metal, spec * dv.Fi_m, ir)
    diel = _mix(diel, rgb_mix(diffuse, spec, dv.Fi_d), ir)
    col = _mix(diel, metal, s.m[:, None])
    scale = _sheen_scale(s, dv, nl)
    col = k * s.shc * (d_charlie(nh, s.shr) * vis_sheen(nl, dv.nv, s.shr))[:, None] + col * scale[:, None]
    nccl, ncch = _c01(_dot(s.Ncc, L)), _c01(_dot(s.Ncc, H))
    coat = I * (nccl * d_ggx(ncch, dv.alpha_cc) * vis_ggx(nccl, dv.nccv, dv.alpha_cc))[:, None]
    return _mix(col, coat, (s.cc * dv.Fc)[:, None])


def _reflect(V, n):
    return _unit(2.0 * _dot(n, V)[:, None] * n - V)


def shade_environment(s: Surface, dv: _Derived, env: Environment, multiscatter=False, spec_base="rgb"):
    """The image-based term (N, 3) before occ and ao."""
    R = R_plain = _reflect(s.V, s.N)
    if dv.At is not None:       # the Sample Renderer's bent normal (getIBLRadianceAnisotropy, direction Ab)
        t = np.cross(dv.Ab, s.V)
        an = np.cross(t, dv.Ab)
        bend = (1.0 - s.aniso * (1.0 - s.r)) ** 4
        R = np.where((s.aniso > 0)[:, None], _reflect(s.V, _unit(_mix(an, s.N, bend[:, None]))), R)
    pref = env.prefiltered(R, s.r)
    A, B = dfg(dv.nv, s.r)
    f_diffuse = env.irradiance(s.N) * s.c * ((1.0 - s.dt) * s.dw)[:, None]
    if np.any(s.dt > 0):        # the far hemisphere's light through the surface
        f_diffuse = f_diffuse + env.irradiance(-s.N) * s.dtc * (s.dt * s.dw)[:, None]
    f_metal = fss_ess(s.c, 1.0, dv.nv, s.r, A, B, multiscatter) * pref
    Fd = fss_ess(s.sw[:, None] * dv.f0d, s.sw, dv.nv, s.r, A, B, multiscatter)
    f_diel = _dielectric(f_diffuse, pref, Fd, spec_base)
    ir = dv.irid[:, None]
    f_metal = _mix(f_metal, pref * dv.Fi_m, ir)
    f_diel = _mix(f_diel, rgb_mix(f_diffuse, pref, dv.Fi_d), ir)
    col = _mix(f_diel, f_metal, s.m[:, None])
    msh = _max3(s.shc)
    col = env.prefiltered(R_plain, s.shr) * s.shc * dv.Ev[:, None] + col * np.maximum(1.0 - msh * dv.Ev, 0.0)[:, None]
    return _mix(col, env.prefiltered(_reflect(s.V, s.Ncc), s.ccr), (s.cc * dv.Fc)[:, None])


def shade_layered(surface, lights=(), environment=None, ambient=0.0, multiscatter=False, ao=1.0, *,
                  spec_base="rgb", aniso="model", opd_cos="theta2", f0_guard="clamp"):
    """Linear RGB (N, 3) of the note's layered model: sum over `lights` (dicts, light_inputs) + the ambient
    term (environment: an Environment, or None for the constant `ambient` a) + emission. surface: a Surface
    or a dict for make_surface. ao: SSAO factor (N,) or scalar. multiscatter: RenderConfig.multiscatter.
    spec_base, aniso, opd_cos, f0_guard: the alternatives of layered_pieces' doc (defaults = the note)."""
    s = surface if isinstance(surface, Surface) else make_surface(**surface)
    dv = _derive(s, opd_cos, f0_guard)
    out = np.zeros((len(s.N), 3))
    for light in lights:
        L, I = light_inputs(light, s)
        out += shade_light(s, dv, L, I, spec_base, aniso)
    occ = (s.occ * np.broadcast_to(np.asarray(ao, np.float64), s.occ.shape))[:, None]
    coat = (1.0 - s.cc * dv.Fc)[:, None]
    if environment is None:
        f0 = _mix(s.sw[:, None] * dv.f0d, s.c, s.m[:, None])
        albedo = (s.c * (1.0 - s.dt)[:, None] + s.dtc * s.dt[:, None]) * s.dw[:, None]   # both sides lit alike
        out += (float(ambient) * occ * albedo * (1.0 - s.m)[:, None] * (1.0 - f0)
                * np.maximum(1.0 - _max3(s.shc) * dv.Ev, 0.0)[:, None] * coat)
    else:
        out += shade_environment(s, dv, environment, multiscatter, spec_base) * occ
    return out + s.e * coat
