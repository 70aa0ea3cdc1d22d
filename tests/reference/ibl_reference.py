"""Independent NumPy (float64) references of image-based lighting's precomputed maps (tests/test_ibl.py;
clrender/passes/ibl.py, kernels/ibl.cl, kernels/environment.h; docs/ibl.md): the direction convention,
bilinear lookups, brute-force irradiance and GGX prefiltering by texel sums over the sphere
and the DFG table by Gauss-Legendre quadratures (the SH basis uses clrender's constants: in test_ibl.py)."""
from __future__ import annotations

import numpy as np


def texel_dirs(h: int, w: int) -> np.ndarray:
    """(h, w, 3) float64 directions of the texel centres (the convention of environment.h)."""
    th = np.pi * (np.arange(h) + 0.5) / h
    ph = 2 * np.pi * ((np.arange(w) + 0.5) / w - 0.5)
    th, ph = np.meshgrid(th, ph, indexing="ij")
    return np.stack([np.sin(th) * np.sin(ph), np.cos(th), -np.sin(th) * np.cos(ph)], -1)


def texel_solid_angles(h: int, w: int) -> np.ndarray:
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    return np.broadcast_to(((edges[:-1] - edges[1:]) * 2 * np.pi / w)[:, None], (h, w))


def dir_uv(d: np.ndarray, rotation_deg: float = 0.0):
    d = np.asarray(d, np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    u = (0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi) + rotation_deg / 360.0) % 1.0
    v = np.arccos(np.clip(d[..., 1], -1, 1)) / np.pi
    return u, v


def bilinear(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear RGB at (u, v): texel centres at (i + 0.5) / w, wrapping in u, clamped in v."""
    h, w, _ = img.shape
    fx, fy = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(fx).astype(int), np.floor(fy).astype(int)
    ax, ay = (fx - x0)[:, None], (fy - y0)[:, None]
    xa, xb = x0 % w, (x0 + 1) % w
    ya, yb = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    img = img.astype(np.float64)
    top = img[ya, xa] * (1 - ax) + img[ya, xb] * ax
    bot = img[yb, xa] * (1 - ax) + img[yb, xb] * ax
    return top * (1 - ay) + bot * ay


def sphere_downsample(env: np.ndarray, f: int) -> np.ndarray:
    """f x f blocks averaged with the weights of their texels' solid angles."""
    h, w, _ = env.shape
    wgt = texel_solid_angles(h, w)[..., None]
    num = (env * wgt).reshape(h // f, f, w // f, f, 3).sum((1, 3))
    return num / wgt.reshape(h // f, f, w // f, f, 1).sum((1, 3))


def brute_irradiance(env: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """E(n) / pi = sum over texels of L max(n.w, 0) dOmega / pi."""
    h, w, _ = env.shape
    dirs = texel_dirs(h, w).reshape(-1, 3)
    dO = texel_solid_angles(h, w).reshape(-1)
    cos = np.maximum(normals @ dirs.T, 0.0) * dO
    return cos @ env.reshape(-1, 3).astype(np.float64) / np.pi


def ggx_prefilter(env: np.ndarray, dirs: np.ndarray, rough: float) -> np.ndarray:
    """Brute-force N = V = R GGX convolution: sum L D(h) (n.l) dOmega / sum D(h) (n.l) dOmega."""
    h, w, _ = env.shape
    L = texel_dirs(h, w).reshape(-1, 3)
    dO = texel_solid_angles(h, w).reshape(-1)
    E = env.reshape(-1, 3).astype(np.float64)
    a2 = float(rough) ** 4
    out = np.empty((len(dirs), 3))
    for s in range(0, len(dirs), 512):
        nl = dirs[s:s + 512] @ L.T
        nh2 = np.maximum((1 + nl) / 2, 0)               # h = normalize(n + l): (n.h)^2 = (1 + n.l) / 2
        wgt = np.where(nl > 0, a2 / (np.pi * (nh2 * (a2 - 1) + 1) ** 2) * nl, 0) * dO
        out[s:s + 512] = (wgt @ E) / wgt.sum(1, keepdims=True)
    return out


def gl01(k: int):
    x, w = np.polynomial.legendre.leggauss(k)
    return 0.5 * (x + 1), 0.5 * w


def dfg_reference(nv: float, rough: float, n_phi: int = 32, n_s: int = 128) -> np.ndarray:
    """A, B, C in float64. A, B: over the GGX distribution of h, phi over [0, pi] in two Gauss-Legendre
    halves, theta_h over the part where n.l > 0 in s = sqrt(1 - xi) (smooth integrand); C: plain
    Gauss-Legendre over the cosine-distributed l (smooth)."""
    a2 = float(rough) ** 4
    pg, pw = gl01(n_phi)
    phi = np.concatenate([pg, 1 + pg]) * np.pi / 2
    wphi = np.concatenate([pw, pw]) / 2
    vx = np.sqrt(1 - nv * nv)
    cp = np.cos(phi)[:, None]
    tmax = 0.5 * (np.arctan2(vx * cp, nv) + np.pi / 2)
    smin = np.cos(tmax) * np.sqrt(a2) / np.sqrt(np.sin(tmax) ** 2 + np.cos(tmax) ** 2 * a2)
    sg, sw = gl01(n_s)
    s = smin + sg[None] * (1 - smin)
    wt = sw[None] * (1 - smin) * 2 * s * wphi[:, None]
    den = a2 + s * s * (1 - a2)
    ch, sh = np.sqrt(s * s / den), np.sqrt(a2 * (1 - s * s) / den)
    vh = vx * sh * cp + nv * ch
    nl = np.maximum(2 * vh * ch - nv, 0)
    vis = 0.5 / (nl * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nl * nl * (1 - a2) + a2))
    g = 4 * vis * nl * vh / ch
    fc = (1 - np.clip(vh, 0, 1)) ** 5
    tg, tw = gl01(n_s)
    sl, cl = np.sqrt(tg)[None], np.sqrt(1 - tg)[None]
    dh = np.sqrt(np.maximum(0.5 * (1 + vx * sl * cp + nv * cl), 0))
    C = ((1 - (1 - dh) ** 5) * tw[None] * wphi[:, None]).sum()
    return np.array([(wt * g * (1 - fc)).sum(), (wt * g * fc).sum(), C])


def dfg_plain(nv: float, rough: float, n_phi: int = 256, n_xi: int = 1024) -> np.ndarray:
    """A, B the naive way (an independent check of dfg_reference): Gauss-Legendre over the whole GGX
    CDF xi in [0, 1], the midpoint rule in phi over [0, 2 pi), n.l <= 0 masked."""
    a2 = float(rough) ** 4
    xg, xw = gl01(n_xi)
    P, X = np.meshgrid(2 * np.pi * (np.arange(n_phi) + 0.5) / n_phi, xg, indexing="ij")
    ch = np.sqrt((1 - X) / (1 + (a2 - 1) * X))
    sh = np.sqrt(np.maximum(1 - ch * ch, 0))
    vh = np.sqrt(1 - nv * nv) * sh * np.cos(P) + nv * ch
    nl = 2 * vh * ch - nv
    with np.errstate(all="ignore"):
        vis = 0.5 / (nl * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nl * nl * (1 - a2) + a2))
        g = np.where(nl > 0, 4 * vis * nl * vh / ch, 0.0) * xw[None] / n_phi
    fc = (1 - np.clip(vh, 0, 1)) ** 5
    return np.array([(g * (1 - fc)).sum(), (g * fc).sum()])


def specular_albedo(nv: float, rough: float, n: int = 0) -> float:
    """int D Vis (n.l) dw_l over the hemisphere, in (theta_l, phi_l) (phi over [0, pi]: even): A + B
    when F = 1 (furnace). Narrow lobes need more nodes (n = 0: chosen from the roughness)."""
    n = n or (1200 if rough < 0.5 else 400)
    a2 = float(rough) ** 4
    x, w = np.polynomial.legendre.leggauss(n)
    th, wt = 0.25 * np.pi * (x + 1), 0.25 * np.pi * w
    T, P = np.meshgrid(th, np.pi * (np.arange(n) + 0.5) / n, indexing="ij")
    st, nl = np.sin(T), np.cos(T)
    hx, hz = st * np.cos(P) + np.sqrt(1 - nv * nv), nl + nv
    nh2 = hz * hz / (hx * hx + (st * np.sin(P)) ** 2 + hz * hz)
    D = a2 / (np.pi * (nh2 * (a2 - 1) + 1) ** 2)
    vis = 0.5 / (nl * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nl * nl * (1 - a2) + a2))
    return float((D * vis * nl * st * wt[:, None]).sum() * 2 * np.pi / n)


def c_at_normal() -> float:
    """C(n.v = 1) = 1 - 2 int_0^{pi/2} (1 - cos(theta / 2))^5 cos(theta) sin(theta) dtheta."""
    x, w = np.polynomial.legendre.leggauss(400)
    th, w = np.pi / 4 * (x + 1), np.pi / 4 * w
    return float(1 - 2 * np.sum(w * (1 - np.cos(th / 2)) ** 5 * np.cos(th) * np.sin(th)))
