"""The pieces of the independent NumPy (float64) reference of the layered glTF surface model of issue 37
(layered.py: shade_layered), written from the extension READMEs (KhronosGroup/glTF extensions/2.0/Khronos/
KHR_materials_{ior,specular,clearcoat,sheen,iridescence,anisotropy}/README.md) and the lead's model note, not
from kernels/layered_brdf.h. Every function takes and returns float64 arrays that broadcast.

Choices where the sources differ (DIFFERENCES lists them; the keyword arguments select the alternatives):
- spec_base: the ratified specular README weights the diffuse base by 1 - max3(F_d) ("max3"); the note (and
  the Sample Renderer) by 1 - F_d per channel ("rgb", the default).
- aniso: the anisotropy README has at = mix(alpha, 1, s^2), ab = alpha ("readme"); the note uses the Sample
  Renderer's at = mix(r, 1, s^2)^2, ab = clamp(r^2, 0.001, 1) ("model", the default).
- iridescence: the README's OPD = 2 n_film d cos(theta1) is taken with cos(theta2) (the refracted angle, as in
  Belcour & Barla and every implementation; opd_cos="theta1" gives the README's text); its base-F0 guard
  baseF0 + 1e-4 gives a negative IOR at F0 = 1 (a white metal), so F0 is clamped to [0, 0.9999] instead
  (f0_guard="readme" gives the README's text).
- sheen: the README's Charlie D takes alphaG = sheenRoughness; the note (Sample Renderer) alphaG = max(r, 1e-6)^2.

Definitions of the precomputed quantities (computed here by deterministic quadrature, in float64):
    A(NV, r) = int (1 - (1 - V.H)^5) D(H) Vis(L, V) (N.L) dw_L,  B(NV, r) = int (1 - V.H)^5 D Vis (N.L) dw_L
    over the hemisphere, D = GGX, Vis = the height-correlated Smith visibility G2 / (4 NL NV), alpha = max(r,
    0.01)^2 (Karis 2013's split-sum scale and bias, F0 factored out): ibl_reference.dfg_reference.
    E(mu, r) = int D_charlie(N.H) V_sheen(N.L, mu) (N.L) dw_L (sheen_albedo).
"""
from __future__ import annotations

import numpy as np

from .brdf_reference import MIN_ROUGHNESS
from .ibl_reference import gl01

NV_MIN = 1e-4                   # the note: NV = max(N.V, 1e-4)
SHEEN_MIN_ROUGHNESS = 1e-6      # the Sample Renderer's clamp (0, 1] of the sheen roughness
DIFFERENCES = (
    "specular README: base weighted by 1 - max3(F) (note: 1 - F per channel)",
    "anisotropy README: at = mix(alpha, 1, s^2), ab = alpha (note: mix(r, 1, s^2)^2, clamp(r^2, 1e-3, 1))",
    "iridescence README: OPD with cos(theta1) (here cos(theta2)); F0 + 1e-4 guard (here clamp to 0.9999)",
    "sheen README: alphaG = sheenRoughness (note: sheenRoughness^2)",
)


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _max3(x):
    return np.max(x, axis=-1)


def _mix(a, b, t):
    return a * (1.0 - t) + b * t


def _c01(x):
    return np.clip(x, 0.0, 1.0)


# -- Fresnel -----------------------------------------------------------------------------------------
def f0_from_ior(ior, outside_ior=1.0):
    """KHR_materials_ior, "Implementation": F0 = ((ior - outside) / (ior + outside))^2; ior = 0 gives 1
    (the README's special value; the formula gives it)."""
    ior = np.asarray(ior, np.float64)
    return ((ior - outside_ior) / (ior + outside_ior)) ** 2


def fresnel_schlick(f0, f90, x):
    """glTF 2.0 Appendix B.3.4 (Schlick), with the specular README's F90: f0 + (f90 - f0)(1 - x)^5, x clamped
    to [0, 1]. Broadcasts (x scalar or (...), f0/f90 (..., 3) give (..., 3) with x[..., None])."""
    x = _c01(np.asarray(x, np.float64))
    return f0 + (f90 - f0) * (1.0 - x) ** 5


def rgb_mix(a, b, F):
    """The note's rgb_mix (KHR_materials_iridescence with the specular README's max3 rule for the base):
    (1 - max3(F)) a + F b."""
    return (1.0 - _max3(F))[..., None] * a + F * b


# -- GGX ---------------------------------------------------------------------------------------------
def d_ggx(nh, alpha):
    """Appendix B.3.2 (Trowbridge-Reitz): alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2), alpha = r^2."""
    a2 = np.asarray(alpha, np.float64) ** 2
    q = nh * nh * (a2 - 1.0) + 1.0
    return a2 / (np.pi * q * q)


def vis_ggx(nl, nv, alpha):
    """Appendix B.3.3 (Smith joint, height-correlated): 0.5 / (NL sqrt(NV^2 (1 - a2) + a2) + NV sqrt(NL^2
    (1 - a2) + a2)), a2 = alpha^2; 0 where the denominator is 0."""
    a2 = np.asarray(alpha, np.float64) ** 2
    den = nl * np.sqrt(nv * nv * (1.0 - a2) + a2) + nv * np.sqrt(nl * nl * (1.0 - a2) + a2)
    with np.errstate(divide="ignore"):
        return np.where(den > 0, 0.5 / np.where(den > 0, den, 1.0), 0.0)


def d_ggx_aniso(nh, th, bh, at, ab):
    """KHR_materials_anisotropy, "Implementation" (D_GGX_anisotropic, Burley 2012):
    a2 = at ab, w2 = a2 / |(ab T.H, at B.H, a2 N.H)|^2, D = a2 w2^2 / pi."""
    a2 = at * ab
    w2 = a2 / ((ab * th) ** 2 + (at * bh) ** 2 + (a2 * nh) ** 2)
    return a2 * w2 * w2 / np.pi


def vis_ggx_aniso(nl, nv, tv, bv, tl, bl, at, ab):
    """KHR_materials_anisotropy, "Implementation" (V_GGX_anisotropic, Heitz 2014 height-correlated):
    clamp01(0.5 / (NL |(at T.V, ab B.V, NV)| + NV |(at T.L, ab B.L, NL)|))."""
    gv = nl * np.sqrt((at * tv) ** 2 + (ab * bv) ** 2 + nv * nv)
    gl = nv * np.sqrt((at * tl) ** 2 + (ab * bl) ** 2 + nl * nl)
    with np.errstate(divide="ignore"):
        return _c01(0.5 / (gv + gl))


def aniso_alphas(r, strength, variant="model"):
    """(at, ab) along the anisotropy direction and across it. "model": the note (Sample Renderer brdf.glsl)
    at = mix(r, 1, s^2)^2, ab = clamp(r^2, 0.001, 1); "readme": KHR_materials_anisotropy's
    at = mix(alpha, 1, s^2), ab = alpha, alpha = max(r, 0.01)^2 (clrender's minimum)."""
    r = np.asarray(r, np.float64)
    s2 = np.asarray(strength, np.float64) ** 2
    if variant == "model":
        return _mix(r, 1.0, s2) ** 2, np.clip(r * r, 0.001, 1.0)
    if variant == "readme":
        alpha = np.maximum(r, MIN_ROUGHNESS) ** 2
        return _mix(alpha, 1.0, s2), alpha
    raise ValueError(f"aniso variant {variant!r}: expected 'model' or 'readme'")


# -- sheen -------------------------------------------------------------------------------------------
def _sheen_alpha(rough):
    return np.maximum(np.asarray(rough, np.float64), SHEEN_MIN_ROUGHNESS) ** 2


def d_charlie(nh, rough):
    """KHR_materials_sheen "Sheen distribution" (Conty & Kulla 2017): (2 + 1/a) sin(theta_h)^(1/a) / (2 pi),
    a = max(rough, 1e-6)^2 (the Sample Renderer's clamp and square; the README writes a = rough).
    Evaluated in logs: 1/a reaches 1e12."""
    inv = 1.0 / _sheen_alpha(rough)
    s2 = np.maximum(1.0 - np.asarray(nh, np.float64) ** 2, 0.0)
    with np.errstate(divide="ignore"):
        return np.exp(np.log((2.0 + inv) / (2.0 * np.pi)) + 0.5 * inv * np.log(s2))


def _sheen_l(x, alpha_g):
    t = (1.0 - alpha_g) ** 2
    a, b, c = _mix(21.5473, 25.3245, t), _mix(3.82987, 3.32435, t), _mix(0.19823, 0.16801, t)
    d, e = _mix(-1.97760, -1.27393, t), _mix(-4.32054, -4.85967, t)
    return a / (1.0 + b * np.power(x, c)) + d * x + e


def lambda_sheen(cos_theta, alpha_g):
    """KHR_materials_sheen "Sheen visibility": the Charlie Lambda with Estevez & Kulla's numeric fit;
    exp(l(x)) for |x| < 0.5, else exp(2 l(0.5) - l(1 - x)). alpha_g is the squared sheen roughness here."""
    x = np.abs(np.asarray(cos_theta, np.float64))
    lo = np.exp(_sheen_l(np.minimum(x, 0.5), alpha_g))
    hi = np.exp(2.0 * _sheen_l(0.5, alpha_g) - _sheen_l(np.clip(1.0 - x, 0.0, 0.5), alpha_g))
    return np.where(x < 0.5, lo, hi)


def vis_sheen(nl, nv, rough):
    """KHR_materials_sheen "Sheen visibility" (Charlie; not Ashikhmin), clamped to [0, 1] as the Sample
    Renderer: clamp01(1 / ((1 + Lambda(NV) + Lambda(NL)) 4 NV NL))."""
    ag = _sheen_alpha(rough)
    den = (1.0 + lambda_sheen(nv, ag) + lambda_sheen(nl, ag)) * 4.0 * nv * nl
    with np.errstate(divide="ignore"):
        return _c01(np.where(den > 0, 1.0 / np.where(den > 0, den, 1.0), 1.0))


def _graded_nodes(n_levels, n_gl):
    """Fractions of [0, 1] and weights: n_levels intervals graded geometrically towards 1 (widths 1/2, 1/4,
    ..., the last one up to 1), n_gl Gauss-Legendre nodes each."""
    q = np.concatenate([1.0 - 0.5 ** np.arange(n_levels), [1.0]])
    g, w = gl01(n_gl)
    frac = (q[:-1, None] + (q[1:] - q[:-1])[:, None] * g[None]).ravel()
    return frac, ((q[1:] - q[:-1])[:, None] * w[None]).ravel()


def sheen_albedo(mu, rough, n_phi=(8, 12), n_theta=(24, 16)):
    """E(mu, rough) = int D_charlie(N.H) V_sheen(N.L, mu) (N.L) dw_L over the hemisphere (the sheen README's
    E(x), "Albedo-scaling technique"), for a view at cos(theta_v) = mu. Arrays broadcast.

    Quadrature (deterministic): over the half vector h (dw_L = 4 (V.H) dw_h), phi_h over [0, pi] (the
    integrand is even), each half [0, pi/2], [pi/2, pi] in n_phi[0] intervals graded geometrically towards
    pi/2 (where the N.L > 0 boundary turns within ~mu), n_phi[1] Gauss-Legendre nodes each; theta_h over
    exactly the part where N.L > 0, theta_h < t(phi) = (atan2(sin_v cos phi, mu) + pi/2) / 2, in n_theta[0]
    intervals graded towards t (D peaks there with a width ~ rough^2), n_theta[1] nodes each. Doubling the
    counts changes E by < 1e-5 over mu, rough in [0.02, 1] (self-tests), which agrees with a brute-force
    Monte Carlo."""
    mu, rough = np.broadcast_arrays(np.asarray(mu, np.float64), np.asarray(rough, np.float64))
    shape = mu.shape
    mu, rough = mu.ravel(), rough.ravel()
    pf, pw = _graded_nodes(*n_phi)
    phi = np.concatenate([pf, 2.0 - pf]) * np.pi / 2
    wphi = np.concatenate([pw, pw]) * np.pi / 2 * 2.0            # x2: phi over [pi, 2 pi] by symmetry
    order = np.argsort(rough, kind="stable")                     # chunks of similar roughness share a grading
    out = np.empty(mu.size)
    for s in range(0, mu.size, 32):
        idx = order[s:s + 32]
        # grade down to ~ 2^-8 of the narrowest peak (width ~ a) of the chunk, at most n_theta[0] levels
        need = int(np.ceil(np.log2(1.0 / _sheen_alpha(rough[idx]).min()))) + 8
        frac, wfrac = _graded_nodes(int(np.clip(need, 8, n_theta[0])), n_theta[1])
        nv = np.clip(mu[idx], 0.0, 1.0)[:, None, None]
        rr = rough[idx][:, None, None]
        vx = np.sqrt(1.0 - nv * nv)
        cp = np.cos(phi)[None, :, None]
        tmax = 0.5 * (np.arctan2(vx * cp, nv) + np.pi / 2)
        th = tmax * frac[None, None, :]
        st, ct = np.sin(th), np.cos(th)
        vh = vx * st * cp + nv * ct
        nl = 2.0 * vh * ct - nv
        ok = (nl > 0) & (vh > 0)
        nl = np.where(ok, nl, 0.0)
        f = d_charlie(ct, rr) * vis_sheen(nl, nv, rr) * nl * 4.0 * vh * st
        wt = tmax * wfrac[None, None, :] * wphi[None, :, None]
        out[idx] = np.where(ok, f * wt, 0.0).sum((1, 2))
    return out.reshape(shape)


def _sheen_albedo_cached(mu, rough):
    """sheen_albedo over the distinct (mu, rough) pairs only (per-light E(NL) repeats values)."""
    pairs = np.stack([np.ravel(mu), np.ravel(rough)], -1)
    uniq, inv = np.unique(pairs, axis=0, return_inverse=True)
    return sheen_albedo(uniq[:, 0], uniq[:, 1])[inv.ravel()].reshape(np.shape(mu))


# -- iridescence (KHR_materials_iridescence, Belcour & Barla 2017) ------------------------------------
XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])
SENS_VAL = np.array([5.4856e-13, 4.4201e-13, 5.2481e-13])
SENS_POS = np.array([1.6810e+06, 1.7953e+06, 2.2084e+06])
SENS_VAR = np.array([4.3278e+09, 9.3046e+09, 6.6121e+09])
SENS_X2 = (9.7470e-14, 2.2399e+06, 4.5282e+09)       # the second Gaussian of x: value, position, variance
SENS_NORM = 1.0685e-7


def eval_sensitivity(opd_nm, shift):
    """The README's "Analytic Spectral Integration" evalSensitivity: the Fourier transform of the XYZ fit at
    the optical path difference opd (nm), phase shift `shift` (..., 3), as Rec.709 RGB (..., 3)."""
    phase = (2.0 * np.pi * 1e-9 * np.asarray(opd_nm, np.float64))[..., None]
    shift = np.asarray(shift, np.float64)
    xyz = SENS_VAL * np.sqrt(2 * np.pi * SENS_VAR) * np.cos(SENS_POS * phase + shift) * np.exp(-phase ** 2 * SENS_VAR)
    v, p, var = SENS_X2
    x2 = v * np.sqrt(2 * np.pi * var) * np.cos(p * phase[..., 0] + shift[..., 0]) * np.exp(-var * phase[..., 0] ** 2)
    xyz = xyz + np.stack([x2, np.zeros_like(x2), np.zeros_like(x2)], -1)
    return (xyz / SENS_NORM) @ XYZ_TO_REC709.T


def thin_film_terms(outside_ior, film_ior, cos_theta1, thickness_nm, base_f0, opd_cos="theta2", f0_guard="clamp"):
    """The README's interface terms ("Material Interfaces", "Phase Shift", "Compound terms") as a dict of
    arrays: R12, T121, R23 (..., 3), r123, C0, C1 (first pair of diracs' amplitude, Cm = C1 r123^(m-1)),
    OPD (nm), phi (..., 3), tir (bool: total internal reflection, then F = 1)."""
    n1, n2 = float(outside_ior), np.asarray(film_ior, np.float64)
    c1 = np.asarray(cos_theta1, np.float64)
    d = np.asarray(thickness_nm, np.float64)
    f0b = np.asarray(base_f0, np.float64)
    s2sq = (n1 / n2) ** 2 * (1.0 - c1 * c1)
    tir = s2sq > 1.0
    c2 = np.sqrt(np.maximum(1.0 - s2sq, 0.0))
    R0 = f0_from_ior(n2, n1)
    R12 = fresnel_schlick(R0, 1.0, c1)
    T121 = 1.0 - R12
    phi21 = np.pi - np.where(n2 < n1, np.pi, 0.0)
    f0g = np.clip(f0b, 0.0, 0.9999) if f0_guard == "clamp" else f0b + 0.0001
    base_ior = (1.0 + np.sqrt(f0g)) / (1.0 - np.sqrt(f0g))
    R1 = f0_from_ior(base_ior, np.asarray(n2)[..., None])
    R23 = fresnel_schlick(R1, 1.0, np.asarray(c2)[..., None])
    phi23 = np.where(base_ior < np.asarray(n2)[..., None], np.pi, 0.0)
    opd = 2.0 * n2 * d * (c2 if opd_cos == "theta2" else c1)
    R123 = np.clip(np.asarray(R12)[..., None] * R23, 1e-5, 0.9999)
    r123 = np.sqrt(R123)
    T = np.asarray(T121)[..., None]
    Rs = T * T * R23 / (1.0 - R123)
    return dict(R12=R12, T121=T121, R23=R23, r123=r123, Rs=Rs, C0=np.asarray(R12)[..., None] + Rs,
                C1=(Rs - T) * r123, OPD=opd, phi=np.asarray(phi21)[..., None] + phi23, tir=tir)


def eval_iridescence(outside_ior, film_ior, cos_theta1, thickness_nm, base_f0, opd_cos="theta2",
                     f0_guard="clamp"):
    """F_iridescence of KHR_materials_iridescence "Implementation Notes" (..., 3): I = C0 + sum_{m=1,2}
    Cm 2 S(m OPD, m phi), Cm = (Rs - T121) r123^m, clamped at 0; 1 under total internal reflection.
    cos_theta1, thickness (..,), base_f0 (..., 3). See the module doc for opd_cos and f0_guard."""
    t = thin_film_terms(outside_ior, film_ior, cos_theta1, thickness_nm, base_f0, opd_cos, f0_guard)
    I, Cm = t["C0"], t["C1"]
    for m in (1, 2):
        I = I + Cm * 2.0 * eval_sensitivity(m * t["OPD"], m * t["phi"])
        Cm = Cm * t["r123"]
    return np.where(np.asarray(t["tir"])[..., None], 1.0, np.maximum(I, 0.0))


# -- split sum ---------------------------------------------------------------------------------------
_GL = {}


def _gl(n):
    if n not in _GL:
        _GL[n] = gl01(n)
    return _GL[n]


def dfg(nv, r, n_phi=32, n_s=128):
    """(A, B) of the module doc at (clamp(NV, 1e-4, 1), max(r, 0.01)), vectorized: the quadrature of
    ibl_reference.dfg_reference (phi_h over [0, pi] in two Gauss-Legendre halves; theta_h over the part with
    N.L > 0 in s = sqrt(1 - xi), xi the GGX CDF), with the nodes computed once (tests: equal to it)."""
    shape = np.shape(nv)
    nv = np.clip(np.ravel(np.asarray(nv, np.float64)), NV_MIN, 1.0)        # N.V can round above 1
    a2 = np.broadcast_to(np.maximum(np.ravel(np.asarray(r, np.float64)), MIN_ROUGHNESS) ** 4, nv.shape)
    pg, pw = _gl(n_phi)
    phi = np.concatenate([pg, 1 + pg]) * np.pi / 2
    wphi = np.concatenate([pw, pw]) / 2
    sg, sw = _gl(n_s)
    A, B = np.empty(nv.size), np.empty(nv.size)
    for k in range(0, nv.size, 16):
        v, q = nv[k:k + 16, None, None], a2[k:k + 16, None, None]
        vx, cp = np.sqrt(1 - v * v), np.cos(phi)[None, :, None]
        tmax = 0.5 * (np.arctan2(vx * cp, v) + np.pi / 2)
        smin = np.cos(tmax) * np.sqrt(q) / np.sqrt(np.sin(tmax) ** 2 + np.cos(tmax) ** 2 * q)
        s = smin + sg[None, None] * (1 - smin)
        wt = sw[None, None] * (1 - smin) * 2 * s * wphi[None, :, None]
        den = q + s * s * (1 - q)
        ch, sh = np.sqrt(s * s / den), np.sqrt(q * (1 - s * s) / den)
        vh = vx * sh * cp + v * ch
        nl = np.maximum(2 * vh * ch - v, 0)
        vis = 0.5 / (nl * np.sqrt(v * v * (1 - q) + q) + v * np.sqrt(nl * nl * (1 - q) + q))
        g = wt * 4 * vis * nl * vh / ch
        fc = (1 - np.clip(vh, 0, 1)) ** 5
        A[k:k + 16], B[k:k + 16] = (g * (1 - fc)).sum((1, 2)), (g * fc).sum((1, 2))
    return A.reshape(shape), B.reshape(shape)


def fss_ess(f0, w, nv, r, A, B, multiscatter=False):
    """Fdez-Aguera 2019 as the Sample Renderer's getIBLGGXFresnel: w (kS A + B), kS = F0 + (max(1 - r, F0)
    - F0)(1 - NV)^5; multiscatter adds Ems FssEss Favg / (1 - Favg Ems), Ems = 1 - (A + B),
    Favg = w (F0 + (1 - F0) / 21). f0 (..., 3); w, nv, r, A, B (...)."""
    f0 = np.asarray(f0, np.float64)
    w, nv, r, A, B = (np.asarray(x, np.float64)[..., None] for x in (w, nv, r, A, B))
    kS = f0 + (np.maximum(1.0 - r, f0) - f0) * (1.0 - nv) ** 5
    fss = w * (kS * A + B)
    if not multiscatter:
        return fss
    ems = 1.0 - (A + B)
    favg = w * (f0 + (1.0 - f0) / 21.0)
    return fss + ems * fss * favg / (1.0 - favg * ems)


