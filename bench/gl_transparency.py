"""OpenGL peer for transparency: classic front-to-back depth peeling on Mesa llvmpipe.

``GLTransparencyPeer`` extends ``bench.gl_lights.GLLightsPeer`` (itself GLPeer's G-buffer pass
plus the report's deferred light accumulation) and draws a scene's ``BLEND`` triangles with
depth peeling (Everitt 2001, "Interactive Order-Independent Transparency"; front-to-back "under"
blending as in Bavoil & Myers 2008, "Order Independent Transparency with Dual Depth Peeling"):

1. **Opaque pass** -- GLLightsPeer's frame on the scene's non-BLEND triangles only (OPAQUE and
   MASK): G-buffer MRTs, instanced light proxies accumulating the report's Blinn-Phong point and
   spot lights (attenuation (1 - (d/r)^2)^3), global multiply -> the opaque colour (RGBA32F,
   linear HDR, 0 on background) and the opaque linear view depth (R32F, 0 on background).
2. **N peels** of the transparent geometry.  Peel k renders every BLEND triangle (one draw per
   material; single-sided materials cull back faces, as clrender's setup does) into a peel
   framebuffer: a premultiplied RGBA32F layer colour and a 32-bit float depth texture, depth
   test ``GL_LESS``.  The fragment shader discards a fragment unless it is strictly in front of
   the opaque surface (its view depth ``1/gl_FragCoord.w`` < the G-buffer's view depth, the
   definition clrender uses) and, for k > 0, strictly behind the previous peel
   (``gl_FragCoord.z > `` the previous peel's depth texture, read with ``texelFetch``: the two
   peel framebuffers ping-pong).  So peel k holds, per pixel, the k-th nearest transparent
   fragment.  Surviving fragments are lit *forward* by the same model as the opaque pass:
   ``c = albedo * (ambient + sum A S max(N.L, 0) color) + sum A S spec color``, every light of
   the scene read from an SSBO (no culling: the scene's lights are few), albedo = base colour
   factor x texture (sRGB decoded), alpha = base_color.a x opacity x texture.a, the interpolated
   vertex normal flipped on back faces, P the interpolated world position.
3. After each peel a full-screen triangle blends the layer *under* the accumulator
   (RGBA32F, cleared to (0, 0, 0, 1): rgb = accumulated colour, a = transmittance T) with
   ``glBlendFuncSeparate(DST_ALPHA, ONE, ZERO, ONE_MINUS_SRC_ALPHA)``:
   ``acc += T * (alpha * c); T *= (1 - alpha)``, clrender's front-to-back formula.
4. A last full-screen triangle composites ``color = acc + T * opaque_color``.

``time_frame`` times all of it + ``glFinish`` + the readback of the final colour (RGB float32),
as the clrender benchmarks time ``render()``.  ``time_frame_opaque_only`` times step 1 alone.
There is no occlusion-query early exit: every frame peels exactly ``peel_layers`` layers, like
clrender's ``transparency="depth_peeling"``.  ``fragment_count(camera)`` (untimed) counts the
transparent fragments in front of the opaque surface per pixel (additive blending), to compare
with clrender's ``Frame.fragment_count``.

``render(camera)`` returns GLLightsPeer's dict (the G-buffer and ``color`` of the *opaque* pass,
renamed ``opaque_color``) plus ``color`` (H, W, 3) float32, the composited linear HDR frame, and
``transmittance`` (H, W) float32; row 0 at the top.

Differences from clrender (expected, small): GL's own rasterization rules (see GLPeer);
coplanar transparent fragments at exactly the same window depth are peeled together in one
layer (clrender orders them by triangle id and peels them one by one); the sun and shadow maps
are not drawn (the transparency benchmark uses point lights only, shadows off); the opaque
light buffer is RGBA16F by default (GLLightsPeer's ``accum_dtype``), the transparent lighting
float32.
"""
from __future__ import annotations

import ctypes
import dataclasses
import time

import numpy as np

from bench.gl_lights import GLLightsPeer, _light_instances
from bench.gl_peer import _Unused, _gl_proc

__all__ = ["GLTransparencyPeer", "split_scene"]

_GL_TEXTURE_2D = 0x0DE1
_GL_DEPTH_COMPONENT = 0x1902
_GL_DEPTH_COMPONENT32F = 0x8CAC
_GL_FLOAT = 0x1406
_GL_TEXTURE_INTERNAL_FORMAT = 0x1003

_PEEL_VS = """
#version 450 core
layout(location = 0) in vec3 in_pos;
layout(location = 1) in vec3 in_nrm;
layout(location = 2) in vec2 in_uv;
uniform mat4 u_mvp;
out vec3 v_pos;
out vec3 v_nrm;
out vec2 v_uv;
void main() {
    gl_Position = u_mvp * vec4(in_pos, 1.0);
    v_pos = in_pos;
    v_nrm = in_nrm;
    v_uv = in_uv;
}
"""

_PEEL_FS = """
#version 450 core
in vec3 v_pos;
in vec3 v_nrm;
in vec2 v_uv;
uniform vec4 u_base_color;      // factor; a already multiplied by the material's opacity
uniform int u_has_tex;
uniform sampler2D u_tex;
uniform vec2 u_spec;            // (intensity, power)
uniform float u_ambient;
uniform vec3 u_eye;
uniform int u_n_lights;
uniform int u_first;            // 1: first peel, no test against a previous layer
uniform int u_count_only;       // 1: output 1 per fragment in front of the opaque surface
uniform sampler2D u_opaque_depth;   // R32F linear view depth of the opaque pass, 0 = background
uniform sampler2D u_prev_depth;     // previous peel's depth texture (D32F), compare mode off
layout(std430, binding = 1) readonly buffer Lights { vec4 lights[]; };  // 4 vec4 per light
layout(location = 0) out vec4 o_color;   // premultiplied (alpha * c, alpha)
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float z = 1.0 / gl_FragCoord.w;
    float oz = texelFetch(u_opaque_depth, px, 0).r;
    if (oz > 0.0 && !(z < oz))
        discard;                                 // not strictly in front of the opaque surface
    if (u_count_only != 0) {
        o_color = vec4(1.0, 0.0, 0.0, 0.0);
        return;
    }
    if (u_first == 0 && !(gl_FragCoord.z > texelFetch(u_prev_depth, px, 0).r))
        discard;                                 // peeled already
    vec4 c = u_base_color;
    if (u_has_tex != 0)
        c *= texture(u_tex, v_uv);
    vec3 N = normalize(v_nrm);
    if (!gl_FrontFacing)
        N = -N;
    vec3 P = v_pos;
    vec3 V = normalize(u_eye - P);
    vec3 diffuse = vec3(0.0);
    vec3 specular = vec3(0.0);
    for (int i = 0; i < u_n_lights; ++i) {
        vec4 pr = lights[4 * i];
        vec3 Lv = pr.xyz - P;
        float d = length(Lv);
        if (!(d < pr.w))
            continue;
        vec4 ct = lights[4 * i + 1];
        vec3 L = Lv / d;
        float q = d / pr.w;
        float s = 1.0 - q * q;
        float A = s * s * s;
        if (ct.w > 0.5) {                        // spot
            vec4 dc = lights[4 * i + 2];
            float t = clamp((dot(-L, dc.xyz) - dc.w) / max(lights[4 * i + 3].x - dc.w, 1e-4), 0.0, 1.0);
            A *= t * t;
        }
        float NdotL = max(dot(N, L), 0.0);
        if (!(A > 0.0 && NdotL > 0.0))
            continue;
        vec3 h = L + V;
        float spec = 0.0;
        float hh = dot(h, h);
        if (hh > 0.0) {
            float NdotH = max(dot(N, h * inversesqrt(hh)), 0.0);
            spec = u_spec.x * (NdotH > 0.0 ? pow(NdotH, u_spec.y) : 0.0);
        }
        diffuse += A * ct.rgb * NdotL;
        specular += A * ct.rgb * spec;
    }
    vec3 col = c.rgb * (u_ambient + diffuse) + specular;
    float a = clamp(c.a, 0.0, 1.0);
    o_color = vec4(a * col, a);
}
"""

_FULLSCREEN_VS = """
#version 450 core
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

_UNDER_FS = """
#version 450 core
uniform sampler2D u_layer;
layout(location = 0) out vec4 o_color;
void main() {
    o_color = texelFetch(u_layer, ivec2(gl_FragCoord.xy), 0);   // blended under the accumulator
}
"""

_COMPOSITE_FS = """
#version 450 core
uniform sampler2D u_acc;        // rgb: accumulated colour, a: transmittance
uniform sampler2D u_opaque;
layout(location = 0) out vec4 o_color;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 acc = texelFetch(u_acc, px, 0);
    o_color = vec4(acc.rgb + acc.a * texelFetch(u_opaque, px, 0).rgb, acc.a);
}
"""


def split_scene(scene):
    """(scene with only its non-BLEND triangles, indices of the BLEND triangles in ``scene``)."""
    blend_mat = np.array([m.alpha_mode == "BLEND" for m in scene.materials], bool)
    is_blend = blend_mat[scene.triangle_material] if scene.triangle_count else np.zeros(0, bool)
    keep = ~is_blend
    opaque = dataclasses.replace(
        scene, triangles=scene.triangles[keep], triangle_material=scene.triangle_material[keep],
        triangle_mesh=scene.triangle_mesh[keep], triangle_face=scene.triangle_face[keep])
    return opaque, np.flatnonzero(is_blend).astype(np.int32)


class GLTransparencyPeer(GLLightsPeer):
    """GLLightsPeer for the opaque triangles + depth peeling of the BLEND ones. See module doc."""

    def __init__(self, width: int, height: int, *, peel_layers: int = 4, **peer_options):
        """``peel_layers``: layers peeled per frame (>= 1). Other keywords go to GLLightsPeer
        (``accum_dtype``, ``proxy_subdivisions``, ``normal_dtype``, ``albedo_dtype``, ...)."""
        super().__init__(width, height, **peer_options)
        self.peel_layers = int(peel_layers)
        if self.peel_layers < 1:
            raise ValueError(f"peel_layers must be >= 1, got {peel_layers!r}")
        self.n_transparent = 0
        self._t_objs: list = []
        self._t_groups: list[dict] = []
        self._t_vao = None
        self._light_ssbo = None
        self._n_forward_lights = 0
        mgl = self.moderngl
        with self.ctx:
            ctx = self.ctx
            size = (self.width, self.height)
            self.peel_prog = ctx.program(vertex_shader=_PEEL_VS, fragment_shader=_PEEL_FS)
            self._pu = {n: (self.peel_prog[n] if n in self.peel_prog else _Unused()) for n in (
                "u_base_color", "u_has_tex", "u_spec", "u_ambient", "u_eye", "u_n_lights", "u_first",
                "u_count_only", "u_tex", "u_opaque_depth", "u_prev_depth")}
            self._pu["u_tex"].value = 0
            self._pu["u_opaque_depth"].value = 1
            self._pu["u_prev_depth"].value = 2
            # Two peel framebuffers (ping-pong): premultiplied layer colour + float32 depth texture.
            self._peel_color, self._peel_depth, self.peel_fbos = [], [], []
            for _ in range(2):
                col = ctx.texture(size, 4, dtype="f4")
                col.filter = (mgl.NEAREST, mgl.NEAREST)
                dep = ctx.depth_texture(size)
                self._make_depth_float(dep)
                dep.compare_func = ""                # plain texelFetch of the stored depth
                dep.filter = (mgl.NEAREST, mgl.NEAREST)
                self._peel_color.append(col)
                self._peel_depth.append(dep)
                self.peel_fbos.append(ctx.framebuffer([col], dep))
            self._acc = ctx.texture(size, 4, dtype="f4")
            self._acc.filter = (mgl.NEAREST, mgl.NEAREST)
            self.acc_fbo = ctx.framebuffer([self._acc])
            self._final = ctx.texture(size, 4, dtype="f4")
            self.final_fbo = ctx.framebuffer([self._final])
            self._count_tex = ctx.texture(size, 1, dtype="f4")
            self.count_fbo = ctx.framebuffer([self._count_tex])
            self._att_color.filter = (mgl.NEAREST, mgl.NEAREST)

            self.under_prog = ctx.program(vertex_shader=_FULLSCREEN_VS, fragment_shader=_UNDER_FS)
            self.under_prog["u_layer"].value = 0
            self._under_vao = ctx.vertex_array(self.under_prog, [])
            self.composite_prog = ctx.program(vertex_shader=_FULLSCREEN_VS, fragment_shader=_COMPOSITE_FS)
            self.composite_prog["u_acc"].value = 0
            self.composite_prog["u_opaque"].value = 1
            self._composite_vao = ctx.vertex_array(self.composite_prog, [])

    def _make_depth_float(self, tex) -> None:
        """Re-specify a moderngl depth texture (D24) as GL_DEPTH_COMPONENT32F, so that the
        stored depth equals the fragment's gl_FragCoord.z exactly (the peel test compares them)."""
        bind = _gl_proc("glBindTexture", None, ctypes.c_uint, ctypes.c_uint)
        image = _gl_proc("glTexImage2D", None, ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                         ctypes.c_int, ctypes.c_int, ctypes.c_uint, ctypes.c_uint, ctypes.c_void_p)
        query = _gl_proc("glGetTextureLevelParameteriv", None, ctypes.c_uint, ctypes.c_int, ctypes.c_uint,
                         ctypes.POINTER(ctypes.c_int))
        if bind is None or image is None or query is None:
            raise RuntimeError("GLTransparencyPeer: glBindTexture/glTexImage2D unavailable through EGL")
        tex.use(7)                                    # moderngl makes unit 7 active and binds it there
        image(_GL_TEXTURE_2D, 0, _GL_DEPTH_COMPONENT32F, self.width, self.height, 0,
              _GL_DEPTH_COMPONENT, _GL_FLOAT, None)
        bind(_GL_TEXTURE_2D, 0)
        fmt = ctypes.c_int()
        query(tex.glo, 0, _GL_TEXTURE_INTERNAL_FORMAT, ctypes.byref(fmt))
        if fmt.value != _GL_DEPTH_COMPONENT32F:
            raise RuntimeError(f"GLTransparencyPeer: peel depth texture is format {fmt.value:#x}, "
                               "not GL_DEPTH_COMPONENT32F")

    # -- scene / lights -------------------------------------------------------------------------
    def upload(self, scene) -> None:
        """Opaque triangles to GLLightsPeer; BLEND triangles into their own index buffer."""
        t0 = time.perf_counter()
        opaque, blend_ids = split_scene(scene)
        super().upload(opaque)                      # also calls set_lights (-> the SSBO below)
        t1 = time.perf_counter()
        with self.ctx:
            self._release_transparent()
            ctx = self.ctx
            self.n_transparent = int(len(blend_ids))
            if not len(blend_ids):
                return
            if getattr(self, "_vbo", None) is None or self.n_triangles == 0:
                verts = np.empty((len(scene.positions), 8), np.float32)
                verts[:, 0:3], verts[:, 3:6], verts[:, 6:8] = scene.positions, scene.normals, scene.uvs
                vbo = ctx.buffer(verts.tobytes())
                self._t_objs.append(vbo)
            else:
                vbo = self._vbo                       # GLPeer's: the same vertex arrays
            if not self._textures and scene.textures:
                self._textures = [self._make_texture(t) for t in scene.textures]
            mats = scene.triangle_material[blend_ids]
            order = np.argsort(mats, kind="stable")
            tri = np.ascontiguousarray(scene.triangles[blend_ids[order]], dtype=np.int32)
            mat_sorted = mats[order]
            ibo = ctx.buffer(tri.tobytes())
            vao = ctx.vertex_array(self.peel_prog, [(vbo, "3f 3f 2f", "in_pos", "in_nrm", "in_uv")],
                                   index_buffer=ibo, index_element_size=4, skip_errors=True)
            self._t_vao = vao
            self._t_objs += [vao, ibo]
            bounds = np.flatnonzero(np.diff(mat_sorted)) + 1
            starts = np.concatenate([[0], bounds]).astype(np.int64)
            ends = np.concatenate([bounds, [len(tri)]]).astype(np.int64)
            groups = []
            for s, e in zip(starts, ends):
                m = scene.materials[int(mat_sorted[s])]
                bc = tuple(float(c) for c in m.base_color)
                groups.append(dict(
                    start=int(s), count=int(e - s), cull=not m.double_sided, name=m.name,
                    texture=self._textures[m.base_color_texture] if m.base_color_texture >= 0 else None,
                    base_color=(bc[0], bc[1], bc[2], bc[3] * float(m.opacity)),
                    spec=(float(m.specular_intensity), float(m.specular_power))))
            self._t_groups = groups
        self.upload_s += time.perf_counter() - t1
        self.upload_total_s = time.perf_counter() - t0

    def set_lights(self, lights, ambient: float | None = None) -> None:
        super().set_lights(lights, ambient)
        inst = _light_instances(lights)
        packed = np.zeros((max(len(inst), 1), 16), np.float32)   # 4 vec4 per light (std430)
        packed[:len(inst), 0:13] = inst
        with self.ctx:
            if self._light_ssbo is not None:
                self._light_ssbo.release()
            self._light_ssbo = self.ctx.buffer(packed.tobytes())
            self._n_forward_lights = len(inst)

    def _release_transparent(self):
        for obj in self._t_objs:
            obj.release()
        self._t_objs, self._t_groups, self._t_vao, self.n_transparent = [], [], None, 0

    def release(self) -> None:
        with self.ctx:
            self._release_transparent()
            if self._light_ssbo is not None:
                self._light_ssbo.release()
                self._light_ssbo = None
            for obj in (*self.peel_fbos, *self._peel_color, *self._peel_depth, self.acc_fbo, self._acc,
                        self.final_fbo, self._final, self.count_fbo, self._count_tex, self._under_vao,
                        self._composite_vao, self.peel_prog, self.under_prog, self.composite_prog):
                obj.release()
        super().release()

    # -- rendering ------------------------------------------------------------------------------
    def _draw_transparent(self, camera, *, first: bool, count_only: bool = False) -> None:
        """One draw per BLEND material with the peel program (the caller binds the target)."""
        mgl, ctx, u = self.moderngl, self.ctx, self._pu
        mvp = np.asarray(camera.view_projection(self.width, self.height), np.float64).astype(np.float32)
        self.peel_prog["u_mvp"].write(np.ascontiguousarray(mvp.T).tobytes())
        u["u_eye"].value = tuple(float(x) for x in camera.eye)
        u["u_ambient"].value = float(self.ambient)
        u["u_n_lights"].value = int(self._n_forward_lights)
        u["u_first"].value = int(first)
        u["u_count_only"].value = int(count_only)
        self._light_ssbo.bind_to_storage_buffer(1)
        ctx.front_face = "ccw"
        ctx.cull_face = "back"
        culling = None
        for g in self._t_groups:
            if g["cull"] != culling:
                (ctx.enable if g["cull"] else ctx.disable)(mgl.CULL_FACE)
                culling = g["cull"]
            u["u_base_color"].value = g["base_color"]
            u["u_spec"].value = g["spec"]
            if g["texture"] is not None:
                g["texture"].use(0)
                u["u_has_tex"].value = 1
            else:
                u["u_has_tex"].value = 0
            self._t_vao.render(mgl.TRIANGLES, vertices=3 * g["count"], first=3 * g["start"])
        ctx.disable(mgl.CULL_FACE)

    def _peel_and_composite(self, camera) -> None:
        mgl, ctx = self.moderngl, self.ctx
        self.acc_fbo.use()
        self.acc_fbo.clear(0.0, 0.0, 0.0, 1.0)
        if self._t_vao is not None:
            self._att_depth.use(1)
            for k in range(self.peel_layers):
                cur, prev = k & 1, (k & 1) ^ 1
                fbo = self.peel_fbos[cur]
                fbo.use()
                fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
                ctx.enable_only(mgl.DEPTH_TEST)
                ctx.depth_func = "<"
                self._att_depth.use(1)
                self._peel_depth[prev].use(2)
                self._draw_transparent(camera, first=(k == 0))
                # blend the layer under the accumulator
                self.acc_fbo.use()
                ctx.enable_only(mgl.BLEND)
                ctx.blend_equation = mgl.FUNC_ADD
                ctx.blend_func = (mgl.DST_ALPHA, mgl.ONE, mgl.ZERO, mgl.ONE_MINUS_SRC_ALPHA)
                self._peel_color[cur].use(0)
                self._under_vao.render(mgl.TRIANGLES, vertices=3)
        ctx.enable_only(mgl.NOTHING)
        ctx.blend_func = mgl.SRC_ALPHA, mgl.ONE_MINUS_SRC_ALPHA
        self.final_fbo.use()
        self._acc.use(0)
        self._att_color.use(1)
        self._composite_vao.render(mgl.TRIANGLES, vertices=3)

    def _draw(self, camera) -> None:
        """Opaque frame (GLLightsPeer), N peels, composite (no finish, no readback)."""
        super()._draw(camera)
        self._peel_and_composite(camera)

    def _rd(self, fbo, attachment: int, comps: int) -> np.ndarray:
        H, W = self.height, self.width
        a = np.frombuffer(fbo.read(components=comps, attachment=attachment, dtype="f4"), np.float32)
        return np.ascontiguousarray(a.reshape(H, W, comps)[::-1])

    def _read_color(self) -> np.ndarray:
        return self._rd(self.final_fbo, 0, 3)

    def _read(self) -> dict:
        out = super()._read()
        out["opaque_color"] = out.pop("color")
        final = self._rd(self.final_fbo, 0, 4)
        out["color"] = np.ascontiguousarray(final[..., :3])
        out["transmittance"] = np.ascontiguousarray(final[..., 3])
        return out

    def time_frame(self, camera, repeats: int = 10, warmup: int = 3) -> list[float]:
        """Wall-clock ms per frame: opaque pass + peels + composite + glFinish + colour readback."""
        with self.ctx:
            for _ in range(max(0, warmup)):
                self._draw(camera)
                self.ctx.finish()
                self._read_color()
            times = []
            for _ in range(int(repeats)):
                t0 = time.perf_counter()
                self._draw(camera)
                self.ctx.finish()
                self._read_color()
                times.append((time.perf_counter() - t0) * 1e3)
            return times

    def time_frame_opaque_only(self, camera, repeats: int = 10, warmup: int = 3) -> list[float]:
        """Wall-clock ms of the opaque pass alone (GLLightsPeer: G-buffer, lights, combine) + glFinish."""
        with self.ctx:
            for _ in range(max(0, warmup)):
                GLLightsPeer._draw(self, camera)
                self.ctx.finish()
            times = []
            for _ in range(int(repeats)):
                t0 = time.perf_counter()
                GLLightsPeer._draw(self, camera)
                self.ctx.finish()
                times.append((time.perf_counter() - t0) * 1e3)
            return times

    def fragment_count(self, camera) -> np.ndarray:
        """(H, W) int32 transparent fragments strictly in front of the opaque surface (untimed)."""
        mgl, ctx = self.moderngl, self.ctx
        with ctx:
            GLPeer_draw = super(GLLightsPeer, self)._draw      # GLPeer's G-buffer: the opaque depth
            GLPeer_draw(camera)
            self.count_fbo.use()
            self.count_fbo.clear(0.0, 0.0, 0.0, 0.0)
            if self._t_vao is not None:
                ctx.enable_only(mgl.BLEND)
                ctx.blend_equation = mgl.FUNC_ADD
                ctx.blend_func = mgl.ONE, mgl.ONE
                self._att_depth.use(1)
                self._peel_depth[1].use(2)
                self._draw_transparent(camera, first=True, count_only=True)
                ctx.enable_only(mgl.NOTHING)
            c = self._rd(self.count_fbo, 0, 1)[..., 0]
        return np.rint(c).astype(np.int32)

    def info(self) -> dict:
        return {**super().info(), "peel_layers": self.peel_layers, "transparent_triangles": self.n_transparent,
                "transparent_draw_calls": len(self._t_groups), "forward_lights": int(self._n_forward_lights),
                "peel_depth_format": "DEPTH_COMPONENT32F", "layer_format": "RGBA32F"}
