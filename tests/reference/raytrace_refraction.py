"""Ray-traced truth for the refraction geometry of transmissive volumes (docs/transmission.md,
"Where the screen-space method departs"): camera rays refracted into a glass mesh at its real front
surface, through it to its real back surface, refracted out, onto an opaque plane y = 0.

Written from Snell's law and the glTF meshes, never from the renderer's kernels: intersections are
Embree's (the `embreex` module of the `test` extra) on the glass triangles; normals are the mesh's
vertex normals interpolated with Embree's barycentrics (the smooth surface the asset describes), turned
to face the incoming ray; `refract` is GLSL's (k < 0: total internal reflection). Fresnel is not
modelled: only where the light goes. Arithmetic in float64 except Embree's float32 hit distances and
barycentrics, from which the hit points are rebuilt on the float64 triangles.

The plane encodes its own coordinates in its colour so that a renderer's looked-up colour says where it
looked (`RampPlane`): R is a ramp along x, G along z, B a checkerboard. The ramps' node values are
sRGB-uniform (the G-buffer stores colour as sRGB 8 bits), so one code step is the same distance
everywhere: `RampPlane.resolution` world units.

Public API::

    camera_rays(camera, width, height) -> (origins, unit directions), each (H, W, 3)
    project(points, camera, width, height) -> (..., 2) continuous pixel coordinates (x right, y down,
                                              pixel k's centre at k + 0.5)
    refract(i, n, eta) -> (directions, tir mask)
    GlassTracer(positions, normals, faces, ior).trace(origins, dirs) -> Traced
    sphere_plane_points(origins, dirs, center, radius, ior) -> (..., 3): the same through a perfect sphere
    plane_hits(origins, dirs) -> (..., 3) where rays meet y = 0
    RampPlane(x_range, z_range, window_x, window_z, quads, checker) -> .mesh(), .colour_at(p), .decode(rgb)
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .shading import pixel_directions, pixel_origins

EPS = 1e-4           # world units: a secondary ray starts this far along itself, off the surface it left


def camera_rays(camera, width: int, height: int):
    d = pixel_directions(camera, width, height)
    return pixel_origins(camera, width, height), d / np.linalg.norm(d, axis=-1, keepdims=True)


def project(points, camera, width: int, height: int) -> np.ndarray:
    """World points -> continuous pixel coordinates of a perspective or orthographic camera."""
    right, up, back = (np.asarray(v, np.float64) for v in camera.basis())
    v = np.asarray(points, np.float64) - np.asarray(camera.eye, np.float64)
    hx, hy = camera.half_extents(width / height)
    depth = v @ -back
    scale = 1.0 if camera.is_orthographic else depth
    x_ndc = (v @ right) / (scale * hx)
    y_ndc = (v @ up) / (scale * hy)
    return np.stack([(x_ndc + 1.0) * 0.5 * width, (1.0 - y_ndc) * 0.5 * height], -1)


def refract(i, n, eta):
    """GLSL refract: i the unit incident direction, n the unit normal facing it (n·i <= 0), eta the
    ratio of indices (outside / inside when entering). Returns (r, tir) with r = 0 where k < 0."""
    i, n = np.asarray(i, np.float64), np.asarray(n, np.float64)
    c = np.sum(n * i, -1, keepdims=True)
    k = 1.0 - eta * eta * (1.0 - c * c)
    r = eta * i - (eta * c + np.sqrt(np.maximum(k, 0.0))) * n
    tir = k[..., 0] < 0.0
    return np.where(tir[..., None], 0.0, r), tir


@dataclass
class Traced:
    """Per ray: `glass` the camera ray hits the glass; where it does, `entry` / `exit` the points on
    the front and back surfaces, `tir` total internal reflection at the exit (no plane point), `reentry`
    the exit ray hits the glass again (not followed), `plane` the point on y = 0 (NaN where the ray
    does not reach it), `inside_length` the path length in the glass, `theta_t` the angle between the
    refracted ray and the inward normal at the entry."""
    glass: np.ndarray
    entry: np.ndarray
    exit: np.ndarray
    plane: np.ndarray
    tir: np.ndarray
    reentry: np.ndarray
    inside_length: np.ndarray
    theta_t: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        return self.glass & ~self.tir & ~self.reentry & np.isfinite(self.plane).all(-1)


class GlassTracer:
    """Embree over the glass triangles (world positions, vertex normals, faces)."""

    def __init__(self, positions, normals, faces, ior: float):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
        self.p = np.asarray(positions, np.float64)
        self.n = np.asarray(normals, np.float64)
        self.f = np.asarray(faces, np.int64)
        self.ior = float(ior)
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, self.p[self.f].astype(np.float32))

    def _hit(self, o, d):
        """(hit, point, interpolated unit normal) of the nearest intersection along o + t·d, t > 0."""
        r = self.scene.run(o.astype(np.float32), d.astype(np.float32), output=1)
        prim = np.asarray(r["primID"])
        hit = prim >= 0
        pt = np.full(o.shape, np.nan)
        nrm = np.full(o.shape, np.nan)
        if hit.any():
            f = self.f[prim[hit]]
            u, v = np.asarray(r["u"], np.float64)[hit], np.asarray(r["v"], np.float64)[hit]
            w = np.stack([1.0 - u - v, u, v], -1)[..., None]
            pt[hit] = (w * self.p[f]).sum(1)
            nn = (w * self.n[f]).sum(1)
            nrm[hit] = nn / np.linalg.norm(nn, axis=-1, keepdims=True)
        return hit, pt, nrm

    def trace(self, origins, dirs) -> Traced:
        shape = origins.shape[:-1]
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(dirs, np.float64).reshape(-1, 3)
        glass, entry, n1 = self._hit(o, d)
        n1 = np.where((np.sum(n1 * d, -1) > 0)[:, None], -n1, n1)       # facing the camera ray
        r1, _ = refract(d, n1, 1.0 / self.ior)                            # air -> glass: never TIR
        r1 = r1 / np.maximum(np.linalg.norm(r1, axis=-1, keepdims=True), 1e-300)
        cos_t = np.clip(-np.sum(r1 * n1, -1), -1.0, 1.0)
        exit_hit, exit_pt, n2 = self._hit(np.where(glass[:, None], entry + EPS * r1, 0.0),
                                          np.where(glass[:, None], r1, d))
        ok = glass & exit_hit
        n2 = np.where((np.sum(n2 * r1, -1) > 0)[:, None], -n2, n2)       # facing the ray inside
        r2, tir = refract(r1, n2, self.ior)
        tir &= ok
        r2 = r2 / np.maximum(np.linalg.norm(r2, axis=-1, keepdims=True), 1e-300)
        again, _, _ = self._hit(np.where(ok[:, None], exit_pt + EPS * r2, 0.0), np.where(ok[:, None], r2, d))
        reentry = ok & ~tir & again
        t = np.where(r2[:, 1] < 0.0, -exit_pt[:, 1] / np.where(r2[:, 1] < 0.0, r2[:, 1], -1.0), np.nan)
        plane = exit_pt + t[:, None] * r2
        good = ok & ~tir & ~reentry & np.isfinite(t)
        plane[~good] = np.nan
        length = np.where(ok, np.linalg.norm(exit_pt - entry, axis=-1), np.nan)
        return Traced(glass=(glass & exit_hit).reshape(shape), entry=entry.reshape(shape + (3,)),
                      exit=exit_pt.reshape(shape + (3,)), plane=plane.reshape(shape + (3,)),
                      tir=tir.reshape(shape), reentry=reentry.reshape(shape),
                      inside_length=length.reshape(shape), theta_t=np.arccos(cos_t).reshape(shape))


def sphere_plane_points(origins, dirs, center, radius: float, ior: float) -> np.ndarray:
    """The same path through a perfect sphere in closed form (a check of the traced mesh): NaN where
    the ray misses the sphere or does not reach y = 0."""
    o, d = np.asarray(origins, np.float64), np.asarray(dirs, np.float64)
    c = np.asarray(center, np.float64)
    oc = o - c
    b = np.sum(oc * d, -1)
    disc = b * b - (np.sum(oc * oc, -1) - radius * radius)
    p1 = o + (-b - np.sqrt(np.maximum(disc, 0.0)))[..., None] * d
    r1, _ = refract(d, (p1 - c) / radius, 1.0 / ior)
    r1 /= np.linalg.norm(r1, axis=-1, keepdims=True)
    p2 = p1 + (-2.0 * np.sum((p1 - c) * r1, -1))[..., None] * r1           # the chord's far end
    r2, tir = refract(r1, -(p2 - c) / radius, ior)
    out = plane_hits(p2, r2)
    out[(disc <= 0.0) | tir] = np.nan
    return out


def plane_hits(origins, dirs) -> np.ndarray:
    """Where rays meet y = 0 (NaN where they do not)."""
    o, d = np.asarray(origins, np.float64), np.asarray(dirs, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d[..., 1] < 0.0, -o[..., 1] / d[..., 1], np.nan)
    return o + t[..., None] * d


def srgb_to_linear(s):
    s = np.asarray(s, np.float64)
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


class RampPlane:
    """An opaque plane y = 0 over x_range × z_range of quads × quads quads, each with its own four
    vertices (so B can change at cell borders): R(x) and G(z) interpolate node values that are
    sRGB-uniform ramps over window_x / window_z (constant outside: no position can be decoded there),
    linear within a quad (the renderer interpolates vertex colours perspective-correctly); B is a
    checkerboard of `checker` quads per cell, 0.15 / 0.85. Meant for an unlit material with base
    colour white (colour = vertex colour)."""
    LOW, HIGH = 0.15, 0.85

    def __init__(self, x_range, z_range, window_x, window_z, quads: int = 128, checker: int = 8):
        self.xs = np.linspace(*x_range, quads + 1)
        self.zs = np.linspace(*z_range, quads + 1)
        self.window = (tuple(map(float, window_x)), tuple(map(float, window_z)))
        self.quads, self.checker = quads, checker
        self.cell = (self.xs[1] - self.xs[0]) * checker, (self.zs[1] - self.zs[0]) * checker

    def _nodes(self, axis: int):
        nodes = self.xs if axis == 0 else self.zs
        lo, hi = self.window[axis]
        return nodes, srgb_to_linear(np.clip((nodes - lo) / (hi - lo), 0.0, 1.0))

    @property
    def resolution(self):
        """World units per sRGB 8-bit code step of the (x, z) ramps."""
        return tuple((hi - lo) / 255.0 for lo, hi in self.window)

    def mesh(self):
        """(positions (V, 3), normals, colours (V, 4), faces (T, 3)): CCW seen from +y."""
        q = self.quads
        i, j = np.meshgrid(np.arange(q), np.arange(q), indexing="ij")       # i along x, j along z
        i, j = i.ravel(), j.ravel()
        corners = ((0, 0), (0, 1), (1, 1), (1, 0))                           # (di, dj): CCW from +y
        pos = np.stack([np.stack([self.xs[i + di], np.zeros(len(i)), self.zs[j + dj]], -1)
                        for di, dj in corners], 1).reshape(-1, 3)
        _, rx = self._nodes(0)
        _, gz = self._nodes(1)
        parity = ((i // self.checker) + (j // self.checker)) % 2
        b = np.where(parity == 0, self.LOW, self.HIGH)
        col = np.stack([np.stack([rx[i + di], gz[j + dj], b, np.ones(len(i))], -1) for di, dj in corners],
                       1).reshape(-1, 4)
        base = 4 * np.arange(len(i))[:, None]
        faces = np.concatenate([base + (0, 1, 2), base + (0, 2, 3)], 1).reshape(-1, 3)
        normals = np.tile((0.0, 1.0, 0.0), (len(pos), 1))
        return pos, normals, col, faces

    def colour_at(self, points) -> np.ndarray:
        """The plane's exact linear colour at world points (..., 3)."""
        p = np.asarray(points, np.float64)
        xn, rx = self._nodes(0)
        zn, gz = self._nodes(1)
        r, g = np.interp(p[..., 0], xn, rx), np.interp(p[..., 2], zn, gz)
        return np.stack([r, g, self.checker_colour(p)], -1)

    def checker_colour(self, points) -> np.ndarray:
        p = np.asarray(points, np.float64)
        ci = np.floor((p[..., 0] - self.xs[0]) / self.cell[0])
        cj = np.floor((p[..., 2] - self.zs[0]) / self.cell[1])
        return np.where((ci + cj) % 2 == 0, self.LOW, self.HIGH)

    def decode(self, rgb) -> np.ndarray:
        """The plane point whose R, G the colour shows (..., 3); NaN where R or G is at the clamped
        ends of the ramps (outside the windows: nothing to decode)."""
        c = np.asarray(rgb, np.float64)
        xn, rx = self._nodes(0)
        zn, gz = self._nodes(1)
        inside = (c[..., 0] > rx.min()) & (c[..., 0] < rx.max()) & (c[..., 1] > gz.min()) & (c[..., 1] < gz.max())
        x = np.interp(c[..., 0], *_ramp_part(rx, xn))
        z = np.interp(c[..., 1], *_ramp_part(gz, zn))
        out = np.stack([x, np.zeros_like(x), z], -1)
        out[~inside] = np.nan
        return out


def _ramp_part(values, nodes):
    """(values, nodes) of the strictly increasing part of a clamped ramp, with the nodes where it leaves
    the low clamp and reaches the high one."""
    inner = np.flatnonzero((values > values.min()) & (values < values.max()))
    k = np.arange(max(inner[0] - 1, 0), min(inner[-1] + 2, len(values)))
    return values[k], nodes[k]
