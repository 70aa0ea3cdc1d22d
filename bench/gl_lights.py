"""OpenGL peer with lighting: classic deferred shading (the research report's section II.4).

``GLLightsPeer`` extends ``bench.gl_peer.GLPeer`` (whose G-buffer pass it reuses unchanged
apart from two extra outputs) with the report's own light algorithm on the GPU pipeline:

1. **G-buffer** -- GLPeer's MRT pass.  The material's ``specular_intensity`` and
   ``specular_power`` ride in the alpha channels GLPeer leaves unused: albedo.a = intensity,
   normal.a = power (the fragment shader is GLPeer's with one uniform and two assignments
   patched in; the uniform is set per draw alongside GLPeer's own per-draw uniforms).
2. **Light buffer accumulation** -- every light is one instance of a unit icosphere scaled
   so that the polyhedron *contains* the light's sphere of influence (scale = radius /
   inradius of the icosphere).  One instanced draw for all lights (per-instance position,
   radius, color, type, direction, cone cosines), FRONT faces culled, depth test GREATER
   against the G-buffer's D24 depth with depth writes off and depth clamping on (so a back
   face beyond the far plane still lights the surfaces in front of it; one nearer than the near
   plane clamps to depth 0 and fails GREATER, correctly, as everything it bounds is nearer
   than the near plane too), additive blending
   (ONE, ONE) into two MRTs: diffuse and specular (RGBA16F by default, RGBA32F on request).
3. **Global multiply** -- a full-screen triangle: color = albedo * (ambient + diffuse) + specular,
   written to an RGBA32F target (linear HDR).

The light fragment shader evaluates exactly clrender's model: the world position P is
reconstructed from the G-buffer's linear view depth along the pixel-center view ray
(P = eye + depth * (forward + ndc.x * tan(fov/2) * aspect * right + ndc.y * tan(fov/2) * up)),
V = normalize(eye - P), Lv = light.pos - P, d = |Lv|, L = Lv / d,
A = (1 - (d/r)^2)^3 for d < r else 0, S = 1 (point) or t^2 with
t = clamp((dot(-L, dir) - cos_outer) / max(cos_inner - cos_outer, 1e-4), 0, 1) (spot),
NdotL = max(N.L, 0), H = normalize(L + V), spec = intensity * max(N.H, 0)^power where NdotL > 0,
diffuse += A S color NdotL, specular += A S color spec.  Fragments with A S NdotL = 0 are
discarded (they would add exactly zero), so a light contributes nothing -- not even a
rounding error -- at d >= r.

``render(camera)`` returns GLPeer's G-buffer dict plus

* ``specular_intensity`` (H, W) float32, ``specular_power`` (H, W) float32 (0 on background)
* ``diffuse``, ``specular`` (H, W, 3) float32: the light accumulation buffers
* ``color``  (H, W, 3) float32: linear HDR, 0 on background

row 0 at the top.  ``time_frame`` (inherited) times the whole frame: G-buffer + lights +
combine + glFinish; ``time_frame_gbuffer_only`` times GLPeer's pass alone.

Precision: with the default RGBA16F accumulators every blend rounds the running sum to a
half float (11-bit significand, relative step 2^-11 ~ 4.9e-4), so a pixel summing n lights
carries up to ~n/2 * 2^-11 relative rounding error in the worst case (about sqrt(n) typical);
half floats also saturate at 65504.  ``accum_dtype='f4'`` makes the sums float32.
"""
from __future__ import annotations

import time

import numpy as np

from bench.gl_peer import GLPeer, _Unused

__all__ = ["GLLightsPeer", "icosphere", "evaluate_lighting"]

_GL_DEPTH_CLAMP = 0x864F

# Anchors in GLPeer's fragment shader where the specular outputs are patched in.
_PATCHES = (
    ("uniform vec4 u_base_color;", "uniform vec4 u_base_color;\nuniform vec2 u_spec;   // (intensity, power)"),
    ("o_normal = vec4(n, 0.0);", "o_normal = vec4(n, u_spec.y);"),
    ("o_albedo = vec4(c.rgb, 1.0);", "o_albedo = vec4(c.rgb, u_spec.x);"),
)

_LIGHT_VS = """
#version 450 core
layout(location = 0) in vec3 in_pos;            // unit icosphere vertex
layout(location = 1) in vec4 i_pos_radius;      // per instance
layout(location = 2) in vec4 i_color_type;
layout(location = 3) in vec4 i_dir_cos_outer;
layout(location = 4) in float i_cos_inner;
uniform mat4 u_vp;
uniform float u_proxy_scale;                     // 1 / inradius of the unit icosphere
flat out vec4 f_pos_radius;
flat out vec4 f_color_type;
flat out vec4 f_dir_cos_outer;
flat out float f_cos_inner;
void main() {
    vec3 p = i_pos_radius.xyz + in_pos * (i_pos_radius.w * u_proxy_scale);
    gl_Position = u_vp * vec4(p, 1.0);
    f_pos_radius = i_pos_radius;
    f_color_type = i_color_type;
    f_dir_cos_outer = i_dir_cos_outer;
    f_cos_inner = i_cos_inner;
}
"""

_LIGHT_FS = """
#version 450 core
flat in vec4 f_pos_radius;
flat in vec4 f_color_type;
flat in vec4 f_dir_cos_outer;
flat in float f_cos_inner;
uniform sampler2D u_depth;       // linear view depth (R32F)
uniform sampler2D u_normal;      // world normal, a = specular power
uniform sampler2D u_albedo;      // albedo, a = specular intensity
uniform vec3 u_eye;
uniform vec3 u_ray_x;            // world ray at view depth 1 = u_ray_z + ndc.x u_ray_x + ndc.y u_ray_y
uniform vec3 u_ray_y;
uniform vec3 u_ray_z;
uniform vec2 u_inv_size;
layout(location = 0) out vec4 o_diffuse;
layout(location = 1) out vec4 o_specular;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float depth = texelFetch(u_depth, px, 0).r;
    vec2 ndc = gl_FragCoord.xy * u_inv_size * 2.0 - 1.0;      // pixel center, y up
    vec3 P = u_eye + depth * (u_ray_z + ndc.x * u_ray_x + ndc.y * u_ray_y);
    vec3 Lv = f_pos_radius.xyz - P;
    float d = length(Lv);
    float r = f_pos_radius.w;
    if (!(d < r))
        discard;
    vec3 L = Lv / d;
    float q = d / r;
    float s = 1.0 - q * q;
    float A = s * s * s;
    if (f_color_type.w > 0.5) {                 // spot
        float cos_outer = f_dir_cos_outer.w;
        float t = clamp((dot(-L, f_dir_cos_outer.xyz) - cos_outer)
                        / max(f_cos_inner - cos_outer, 1e-4), 0.0, 1.0);
        A *= t * t;
    }
    vec4 nt = texelFetch(u_normal, px, 0);
    vec3 N = normalize(nt.xyz);
    float NdotL = max(dot(N, L), 0.0);
    if (!(A > 0.0 && NdotL > 0.0))
        discard;                                // contributes exactly zero
    vec3 V = normalize(u_eye - P);
    vec3 h = L + V;
    float spec = 0.0;
    float hh = dot(h, h);
    if (hh > 0.0) {
        float NdotH = max(dot(N, h * inversesqrt(hh)), 0.0);
        spec = texelFetch(u_albedo, px, 0).a * (NdotH > 0.0 ? pow(NdotH, nt.a) : 0.0);
    }
    vec3 c = A * f_color_type.rgb;
    o_diffuse = vec4(c * NdotL, 0.0);
    o_specular = vec4(c * spec, 0.0);
}
"""

_COMBINE_VS = """
#version 450 core
void main() {                                   // one full-screen triangle
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

_COMBINE_FS = """
#version 450 core
uniform sampler2D u_albedo;
uniform sampler2D u_diffuse;
uniform sampler2D u_specular;
uniform float u_ambient;
layout(location = 0) out vec4 o_color;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 albedo = texelFetch(u_albedo, px, 0).rgb;
    vec3 diffuse = texelFetch(u_diffuse, px, 0).rgb;
    vec3 specular = texelFetch(u_specular, px, 0).rgb;
    o_color = vec4(albedo * (u_ambient + diffuse) + specular, 1.0);
}
"""


def icosphere(subdivisions: int = 1) -> tuple[np.ndarray, np.ndarray, float]:
    """Unit icosphere: (vertices (V, 3) float64 on the unit sphere, faces (F, 3) CCW seen from
    outside, inradius = distance from the center to the nearest face plane)."""
    t = (1.0 + 5 ** 0.5) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
         (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, np.float64) / np.linalg.norm(p) for p in v]
    faces = [tuple(x) for x in f]
    for _ in range(int(subdivisions)):
        cache: dict = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    V = np.array(verts)
    F = np.array(faces, np.int32)
    p0, p1, p2 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    n = np.cross(p1 - p0, p2 - p0)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    dist = np.einsum("ij,ij->i", n, p0)
    flip = dist < 0                              # make every face CCW seen from outside
    F[flip] = F[flip][:, ::-1]
    inradius = float(np.abs(dist).min())
    return V, F, inradius


def _light_instances(lights) -> np.ndarray:
    """clrender.abi.structs.light_dtype records -> (N, 13) float32 per-instance attributes."""
    lights = np.asarray(lights).reshape(-1)
    out = np.zeros((len(lights), 13), np.float32)
    if len(lights):
        out[:, 0:3] = lights["position"]
        out[:, 3] = lights["radius"]
        out[:, 4:7] = lights["color"]
        out[:, 7] = lights["type"]
        out[:, 8:11] = lights["direction"]
        out[:, 11] = lights["cos_outer"]
        out[:, 12] = lights["cos_inner"]
    return out


class _BaseWithSpec:
    """Stands in for GLPeer's per-draw ``u_base`` uniform: setting it (once per draw, to the
    draw's start in the material-sorted order) also sets that draw's specular uniform."""

    def __init__(self, base, spec, table: dict):
        self._base, self._spec, self.table = base, spec, table

    @property
    def value(self):
        return self._base.value

    @value.setter
    def value(self, start):
        self._base.value = start
        self._spec.value = self.table.get(start, (0.0, 1.0))


class GLLightsPeer(GLPeer):
    """GLPeer + deferred light accumulation (sphere proxies) + global multiply. See module doc."""

    def __init__(self, width: int, height: int, *, accum_dtype: str = "f2", proxy_subdivisions: int = 1,
                 **peer_options):
        """``accum_dtype``: 'f2' (RGBA16F) or 'f4' (RGBA32F) diffuse/specular accumulators.
        ``proxy_subdivisions``: icosphere level of the light proxy (0: 20 faces, 1: 80, 2: 320).
        Other keywords go to GLPeer (``normal_dtype``, ``albedo_dtype``, ``require_llvmpipe``)."""
        if accum_dtype not in ("f2", "f4"):
            raise ValueError(f"accum_dtype must be 'f2' or 'f4', got {accum_dtype!r}")
        super().__init__(width, height, **peer_options)
        self.accum_dtype = accum_dtype
        self.proxy_subdivisions = int(proxy_subdivisions)
        self.n_lights = 0
        self.ambient = 0.0
        self._light_objs: list = []
        self._light_vao = None
        with self.ctx:
            ctx = self.ctx
            # G-buffer program: GLPeer's with the specular outputs patched in.
            from bench import gl_peer
            fs = gl_peer._FRAGMENT_SHADER
            for old, new in _PATCHES:
                if fs.count(old) != 1:
                    raise RuntimeError(f"GLLightsPeer: GLPeer's fragment shader changed; anchor {old!r} not found")
                fs = fs.replace(old, new)
            old_prog = self.prog
            self.prog = ctx.program(vertex_shader=gl_peer._VERTEX_SHADER, fragment_shader=fs)
            if "u_tex" in self.prog:
                self.prog["u_tex"].value = 0
            self._uniforms = [u if isinstance(u, _Unused) else self.prog[u.name] for u in self._uniforms]
            self._spec_table: dict = {}
            self._uniforms[0] = _BaseWithSpec(self._uniforms[0], self.prog["u_spec"], self._spec_table)
            old_prog.release()

            size = (self.width, self.height)
            self._att_diffuse = ctx.texture(size, 4, dtype=accum_dtype)
            self._att_specular = ctx.texture(size, 4, dtype=accum_dtype)
            self._att_color = ctx.texture(size, 4, dtype="f4")
            self.light_fbo = ctx.framebuffer([self._att_diffuse, self._att_specular], self._zbuf)
            self.light_fbo.depth_mask = False
            self.color_fbo = ctx.framebuffer([self._att_color])
            for tex in (self._att_depth, self._att_normal, self._att_albedo, self._att_diffuse,
                        self._att_specular):
                tex.filter = (self.moderngl.NEAREST, self.moderngl.NEAREST)

            self.light_prog = ctx.program(vertex_shader=_LIGHT_VS, fragment_shader=_LIGHT_FS)
            self._light_uniform("u_depth", 0)
            self._light_uniform("u_normal", 1)
            self._light_uniform("u_albedo", 2)
            self._light_uniform("u_inv_size", (1.0 / self.width, 1.0 / self.height))
            verts, faces, inradius = icosphere(self.proxy_subdivisions)
            self.proxy_scale = 1.0 / inradius
            self._light_uniform("u_proxy_scale", self.proxy_scale)
            self._proxy_vbo = ctx.buffer(verts.astype(np.float32).tobytes())
            self._proxy_ibo = ctx.buffer(faces.astype(np.int32).tobytes())
            self.proxy_triangles = len(faces)

            self.combine_prog = ctx.program(vertex_shader=_COMBINE_VS, fragment_shader=_COMBINE_FS)
            for name, unit in (("u_albedo", 0), ("u_diffuse", 1), ("u_specular", 2)):
                self.combine_prog[name].value = unit
            self._combine_vao = ctx.vertex_array(self.combine_prog, [])

    # -- scene / lights -------------------------------------------------------------------------
    def upload(self, scene) -> None:
        """GLPeer's upload, the per-draw specular table, and the scene's lights and ambient."""
        super().upload(scene)
        t0 = time.perf_counter()
        self._spec_table.clear()
        if scene.triangle_count:
            mat_sorted = np.sort(scene.triangle_material, kind="stable")
            for g in self._groups:
                m = scene.materials[int(mat_sorted[g["start"]])]
                self._spec_table[g["start"]] = (float(m.specular_intensity), float(m.specular_power))
        self.set_lights(scene.lights, scene.ambient)
        self.upload_s += time.perf_counter() - t0

    def set_lights(self, lights, ambient: float | None = None) -> None:
        """Replace the lights (clrender.abi.structs.light_dtype records) without re-uploading geometry."""
        inst = _light_instances(lights)
        if ambient is not None:
            self.ambient = float(ambient)
        with self.ctx:
            self._release_lights()
            self.n_lights = len(inst)
            if not len(inst):
                return
            buf = self.ctx.buffer(inst.tobytes())
            self._light_vao = self.ctx.vertex_array(
                self.light_prog,
                [(self._proxy_vbo, "3f", "in_pos"),
                 (buf, "4f 4f 4f 1f/i", "i_pos_radius", "i_color_type", "i_dir_cos_outer", "i_cos_inner")],
                index_buffer=self._proxy_ibo, index_element_size=4, skip_errors=True)
            self._light_objs = [self._light_vao, buf]

    def _release_lights(self):
        for obj in self._light_objs:
            obj.release()
        self._light_objs, self._light_vao, self.n_lights = [], None, 0

    def release(self) -> None:
        with self.ctx:
            self._release_lights()
            for obj in (self.light_fbo, self.color_fbo, self._att_diffuse, self._att_specular, self._att_color,
                        self._proxy_vbo, self._proxy_ibo, self._combine_vao, self.light_prog, self.combine_prog):
                obj.release()
        super().release()

    # -- rendering ------------------------------------------------------------------------------
    def _light_uniform(self, name, value) -> None:
        if name in self.light_prog:                  # a uniform the compiler kept
            self.light_prog[name].value = value

    def _camera_uniforms(self, camera) -> None:
        right, up, back = camera.basis()
        t = np.tan(np.radians(camera.fov_y_deg) / 2.0)
        aspect = self.width / self.height
        self._light_uniform("u_eye", tuple(float(x) for x in camera.eye))
        self._light_uniform("u_ray_x", tuple(float(x) for x in right * (t * aspect)))
        self._light_uniform("u_ray_y", tuple(float(x) for x in up * t))
        self._light_uniform("u_ray_z", tuple(float(x) for x in -back))
        vp = np.asarray(camera.view_projection(self.width, self.height), np.float64).astype(np.float32)
        self.light_prog["u_vp"].write(np.ascontiguousarray(vp.T).tobytes())

    def _draw_lights(self, camera) -> None:
        mgl, ctx = self.moderngl, self.ctx
        self.light_fbo.use()
        self.light_fbo.clear(0.0, 0.0, 0.0, 0.0)          # color only: the depth is the G-buffer's
        if self._light_vao is None:
            return
        self._camera_uniforms(camera)
        self._att_depth.use(0)
        self._att_normal.use(1)
        self._att_albedo.use(2)
        ctx.enable_only(mgl.DEPTH_TEST | mgl.CULL_FACE | mgl.BLEND)
        ctx.enable_direct(_GL_DEPTH_CLAMP)
        ctx.depth_func = ">"
        ctx.front_face = "ccw"
        ctx.cull_face = "front"
        ctx.blend_func = mgl.ONE, mgl.ONE
        ctx.blend_equation = mgl.FUNC_ADD
        self._light_vao.render(mgl.TRIANGLES, instances=self.n_lights)
        ctx.disable_direct(_GL_DEPTH_CLAMP)
        ctx.cull_face = "back"
        ctx.depth_func = "<"
        ctx.enable_only(mgl.NOTHING)

    def _combine(self) -> None:
        self.color_fbo.use()
        self.ctx.enable_only(self.moderngl.NOTHING)
        self.combine_prog["u_ambient"].value = self.ambient
        self._att_albedo.use(0)
        self._att_diffuse.use(1)
        self._att_specular.use(2)
        self._combine_vao.render(self.moderngl.TRIANGLES, vertices=3)

    def _draw(self, camera) -> None:
        """G-buffer (GLPeer), light accumulation, global multiply (no finish, no readback)."""
        super()._draw(camera)
        self._draw_lights(camera)
        self._combine()

    def _read(self) -> dict:
        out = super()._read()
        W, H = self.width, self.height

        def rd(fbo, attachment, comps):
            a = np.frombuffer(fbo.read(components=comps, attachment=attachment, dtype="f4"), np.float32)
            return np.ascontiguousarray(a.reshape(H, W, comps)[::-1])

        normal4 = rd(self.fbo, 1, 4)
        albedo4 = rd(self.fbo, 2, 4)
        out["specular_intensity"] = np.ascontiguousarray(albedo4[..., 3])
        out["specular_power"] = np.ascontiguousarray(normal4[..., 3])
        out["diffuse"] = rd(self.light_fbo, 0, 3)
        out["specular"] = rd(self.light_fbo, 1, 3)
        out["color"] = rd(self.color_fbo, 0, 3)
        return out

    def _read_color_depth(self) -> tuple:
        """What a user of the frame reads: the linear HDR colour and the view depth, row 0 on top."""
        W, H = self.width, self.height
        color = np.frombuffer(self.color_fbo.read(components=3, attachment=0, dtype="f4"), np.float32)
        depth = np.frombuffer(self.fbo.read(components=1, attachment=0, dtype="f4"), np.float32)
        return (np.ascontiguousarray(color.reshape(H, W, 3)[::-1]), np.ascontiguousarray(depth.reshape(H, W)[::-1]))

    def time_frame_readback(self, camera, repeats: int = 10, warmup: int = 3) -> list[float]:
        """Wall-clock ms of the frame a user waits for: G-buffer + lights + combine + glFinish +
        glReadPixels of the colour and the depth into numpy (clrender's counterpart: render()
        then Frame.color and Frame.depth)."""
        return self.time_frame_with_readback(camera, repeats, warmup, read=self._read_color_depth)

    def time_frame_gbuffer_only(self, camera, repeats: int = 10, warmup: int = 3) -> list[float]:
        """Wall-clock ms of GLPeer's G-buffer pass alone (+ glFinish), for a pass breakdown."""
        with self.ctx:
            for _ in range(max(0, warmup)):
                GLPeer._draw(self, camera)
                self.ctx.finish()
            times = []
            for _ in range(int(repeats)):
                t0 = time.perf_counter()
                GLPeer._draw(self, camera)
                self.ctx.finish()
                times.append((time.perf_counter() - t0) * 1e3)
            return times

    def info(self) -> dict:
        return {**super().info(), "lights": self.n_lights, "ambient": self.ambient,
                "accum_format": "RGBA16F" if self.accum_dtype == "f2" else "RGBA32F",
                "proxy_triangles": self.proxy_triangles, "proxy_scale": self.proxy_scale}


# -- reference evaluation ----------------------------------------------------------------------
def evaluate_lighting(gb: dict, camera, lights, ambient: float, *, dtype=np.float64) -> dict:
    """NumPy evaluation of the lighting model at a G-buffer's own values.

    ``gb``: dict with depth (H, W; +inf/any on background), normal, albedo, triangle_id,
    specular_intensity, specular_power (as GLLightsPeer.render returns).  Returns diffuse,
    specular, color (H, W, 3) in ``dtype``; background pixels are 0."""
    tid = np.asarray(gb["triangle_id"])
    H, W = tid.shape
    fg = tid >= 0
    right, up, back = (np.asarray(x, dtype) for x in camera.basis())
    t = np.tan(np.radians(camera.fov_y_deg) / 2.0)
    ndc_x = ((np.arange(W) + 0.5) / W * 2 - 1).astype(dtype)
    ndc_y = (1 - (np.arange(H) + 0.5) / H * 2).astype(dtype)          # row 0 = top
    ray = (-back + ndc_x[None, :, None] * (t * W / H) * right + ndc_y[:, None, None] * t * up)
    depth = np.where(fg, np.asarray(gb["depth"], dtype), 0.0)
    eye = np.asarray(camera.eye, dtype)
    P = eye + depth[..., None] * ray
    N = np.asarray(gb["normal"], dtype)
    N = N / np.maximum(np.linalg.norm(N, axis=-1, keepdims=True), 1e-30)
    V = eye - P
    V /= np.maximum(np.linalg.norm(V, axis=-1, keepdims=True), 1e-30)
    si = np.asarray(gb["specular_intensity"], dtype)
    sp = np.asarray(gb["specular_power"], dtype)
    diffuse = np.zeros((H, W, 3), dtype)
    specular = np.zeros((H, W, 3), dtype)
    for light in np.asarray(lights).reshape(-1):
        Lv = np.asarray(light["position"], dtype) - P
        d = np.linalg.norm(Lv, axis=-1)
        r = dtype(light["radius"])
        inside = fg & (d < r)
        L = Lv / np.maximum(d, 1e-30)[..., None]
        A = np.where(inside, (1 - (d / r) ** 2) ** 3, 0.0)
        if int(light["type"]) == 1:
            co, ci = dtype(light["cos_outer"]), dtype(light["cos_inner"])
            tt = np.clip((np.einsum("ijk,k->ij", -L, np.asarray(light["direction"], dtype)) - co)
                         / max(ci - co, 1e-4), 0.0, 1.0)
            A = A * tt * tt
        ndl = np.maximum(np.einsum("ijk,ijk->ij", N, L), 0.0)
        h = L + V
        h /= np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-30)
        ndh = np.maximum(np.einsum("ijk,ijk->ij", N, h), 0.0)
        spec = np.where(ndl > 0, si * ndh ** sp, 0.0)
        c = np.asarray(light["color"], dtype)
        diffuse += (A * ndl)[..., None] * c
        specular += (A * spec)[..., None] * c
    albedo = np.where(fg[..., None], np.asarray(gb["albedo"], dtype), 0.0)
    color = albedo * (dtype(ambient) + diffuse) + specular
    return {"diffuse": diffuse, "specular": specular, "color": color}
