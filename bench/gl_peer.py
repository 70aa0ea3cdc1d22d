"""OpenGL peer renderer: the same G-buffer as clrender, drawn by a real GL pipeline.

Used by the benchmarks as the performance and correctness peer (it is not part of
the ``clrender`` package).  It renders through ``moderngl`` on a headless EGL context,
normally Mesa llvmpipe, and produces the G-buffer clrender's ``Frame`` carries:

* ``depth``        (H, W)    float32  positive view-space depth, +inf on background
* ``normal``       (H, W, 3) float32  world-space normal, normalized, flipped on back faces
* ``albedo``       (H, W, 3) float32  linear diffuse albedo: factor x texture x (1 - metallic factor)
                   (docs/materials.md; metallic-roughness textures are not sampled)
* ``triangle_id``  (H, W)    int32    original scene triangle index, -1 on background

Row 0 is the top of the image (GL reads bottom-up; ``render`` flips).

Pipeline
--------
* One interleaved VBO (position, normal, uv) shared by all draws, one IBO holding the
  triangles stably sorted by material: one draw call per material, state (culling,
  texture, uniforms) set per draw.
* Triangle id: ``gl_PrimitiveID`` (restarts at 0 in every draw) plus the draw's start in
  the sorted order gives the sorted position; an SSBO maps it back to the original id.
  When a material's triangles are one contiguous id range (the common case for scenes
  whose meshes carry one material), the draw skips the lookup (``id0 + gl_PrimitiveID``).
* Depth: ``1/gl_FragCoord.w`` (the rasterizer's interpolated 1/w_clip, i.e. view depth)
  written to an R32F attachment; visibility by a D24 depth buffer with ``GL_LESS``.
  (GL clears every attachment with the same float value, which an integer attachment
  receives as raw bits, so everything is cleared to 0: ids are stored +1 and background
  depth is set to +inf on readback.)
* Textures: uploaded as stored (row 0 = top of the image, which becomes GL's t = 0), and
  sampled at the glTF uv unchanged, so no flip anywhere.  sRGB textures use
  ``GL_SRGB8_ALPHA8`` (the sampler decodes to linear before filtering, mipmaps from
  ``glGenerateMipmap``), trilinear ``LINEAR_MIPMAP_LINEAR``; wrap repeat/clamp through
  moderngl, mirror through ``glTextureParameteri`` (GL 4.5 DSA, resolved with
  ``eglGetProcAddress``).
* Culling: back faces (glTF CCW front faces) culled for single-sided materials only.
  ``MASK`` materials discard fragments with alpha < cutoff; ``BLEND`` is drawn opaque.

Differences from the clrender raster contract (expected, small): GL's edge rule and
snapping are the driver's (llvmpipe: 8 sub-pixel bits, the GL lower-left rule), depth ties
go to the first drawn fragment (draws are in material order, triangles within a draw in id
order), the far plane clips geometry rather than discarding per pixel, and the depth test
runs on window z (D24) rather than on float32 view depth.
"""
from __future__ import annotations

import ctypes
import time

import numpy as np

__all__ = ["GLPeer", "compare_gbuffers", "gl_available"]

_GL_SRGB8_ALPHA8 = 0x8C43
_GL_TEXTURE_WRAP_S = 0x2802
_GL_TEXTURE_WRAP_T = 0x2803
_GL_MIRRORED_REPEAT = 0x8370

_VERTEX_SHADER = """
#version 450 core
layout(location = 0) in vec3 in_pos;
layout(location = 1) in vec3 in_nrm;
layout(location = 2) in vec2 in_uv;
uniform mat4 u_mvp;
out vec3 v_nrm;
out vec2 v_uv;
void main() {
    gl_Position = u_mvp * vec4(in_pos, 1.0);
    v_nrm = in_nrm;
    v_uv = in_uv;
}
"""

_FRAGMENT_SHADER = """
#version 450 core
in vec3 v_nrm;
in vec2 v_uv;
uniform vec4 u_base_color;
uniform int u_has_tex;
uniform int u_mask;
uniform float u_cutoff;
uniform int u_base;     // start of this draw in the material-sorted triangle order
uniform int u_direct;   // 1: this draw's original ids are u_id0 + gl_PrimitiveID
uniform int u_id0;
uniform sampler2D u_tex;
layout(std430, binding = 0) readonly buffer SortedIds { int sorted_ids[]; };
layout(location = 0) out float o_depth;
layout(location = 1) out vec4 o_normal;
layout(location = 2) out vec4 o_albedo;
layout(location = 3) out int o_id;
void main() {
    vec4 c = u_base_color;
    if (u_has_tex != 0)
        c *= texture(u_tex, v_uv);
    if (u_mask != 0 && c.a < u_cutoff)
        discard;
    vec3 n = normalize(v_nrm);
    if (!gl_FrontFacing)
        n = -n;
    o_depth = 1.0 / gl_FragCoord.w;
    o_normal = vec4(n, 0.0);
    o_albedo = vec4(c.rgb, 1.0);
    int tri = (u_direct != 0) ? (u_id0 + gl_PrimitiveID) : sorted_ids[u_base + gl_PrimitiveID];
    o_id = tri + 1;
}
"""

_shared_ctx = None


def _import_moderngl():
    try:
        import moderngl
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise RuntimeError(f"GLPeer needs moderngl (pip install moderngl): {exc}") from None
    return moderngl


def _context():
    """One shared headless EGL context per process (every GLPeer uses it)."""
    global _shared_ctx
    if _shared_ctx is None:
        moderngl = _import_moderngl()
        try:
            _shared_ctx = moderngl.create_standalone_context(backend="egl", require=450)
        except Exception as exc:
            raise RuntimeError(
                "GLPeer could not create a headless OpenGL 4.5 context through EGL "
                f"({type(exc).__name__}: {exc}). Install libegl1, libegl-mesa0 and "
                "libgl1-mesa-dri (Mesa llvmpipe).") from None
    return _shared_ctx


def gl_available() -> tuple[bool, str]:
    """(True, GL_RENDERER) when an EGL context can be made, else (False, reason)."""
    try:
        ctx = _context()
    except RuntimeError as exc:
        return False, str(exc)
    return True, str(ctx.info.get("GL_RENDERER", "?"))


def _gl_proc(name: str, restype, *argtypes):
    """A GL entry point through eglGetProcAddress (Mesa returns core functions too)."""
    try:
        egl = ctypes.CDLL("libEGL.so.1")
    except OSError:
        return None
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    addr = egl.eglGetProcAddress(name.encode())
    if not addr:
        return None
    return ctypes.CFUNCTYPE(restype, *argtypes)(addr)


class _Unused:
    """Stands in for a uniform the GLSL compiler optimized away."""
    value = None


def diffuse_factor(m) -> tuple:
    """The material's colour factor with clrender's metallic rule (diffuse = base·(1 − metallic)),
    alpha kept; per-pixel metallic-roughness textures are beyond this peer."""
    k = 1.0 if m.metallic is None or m.unlit else 1.0 - m.metallic
    return tuple(float(c) * k for c in m.base_color[:3]) + (float(m.base_color[3]),)


class GLPeer:
    """Renders clrender's G-buffer with OpenGL (moderngl, headless EGL, llvmpipe)."""

    def __init__(self, width: int, height: int, *, require_llvmpipe: bool = True,
                 normal_dtype: str = "f2", albedo_dtype: str = "f2"):
        """``normal_dtype``/``albedo_dtype``: 'f2' (RGBA16F), 'f4' (RGBA32F) or, for albedo,
        'f1' (RGBA8 UNORM) -- the attachment formats."""
        if int(width) < 1 or int(height) < 1:
            raise ValueError(f"GLPeer size must be positive, got {width}x{height}")
        self.width, self.height = int(width), int(height)
        self.moderngl = _import_moderngl()
        self.ctx = _context()
        self.renderer = str(self.ctx.info.get("GL_RENDERER", "?"))
        if require_llvmpipe and "llvmpipe" not in self.renderer.lower():
            raise RuntimeError(f"GLPeer requires Mesa llvmpipe, but EGL gave {self.renderer!r} "
                               "(pass require_llvmpipe=False to accept it)")
        if normal_dtype not in ("f2", "f4") or albedo_dtype not in ("f1", "f2", "f4"):
            raise ValueError("normal_dtype must be 'f2'/'f4', albedo_dtype 'f1'/'f2'/'f4'")
        self._scene_objs: list = []
        self._groups: list[dict] = []
        self._textures: list = []
        self.n_triangles = 0
        self.upload_s = 0.0
        with self.ctx:
            ctx = self.ctx
            self.prog = ctx.program(vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER)
            size = (self.width, self.height)
            self._att_depth = ctx.texture(size, 1, dtype="f4")
            self._att_normal = ctx.texture(size, 4, dtype=normal_dtype)
            self._att_albedo = ctx.texture(size, 4, dtype=albedo_dtype)
            self._att_id = ctx.texture(size, 1, dtype="i4")
            self._zbuf = ctx.depth_renderbuffer(size)
            self.fbo = ctx.framebuffer(
                [self._att_depth, self._att_normal, self._att_albedo, self._att_id], self._zbuf)
            if "u_tex" in self.prog:
                self.prog["u_tex"].value = 0
            self._uniforms = [self.prog[n] if n in self.prog else _Unused() for n in
                              ("u_base", "u_direct", "u_id0", "u_base_color", "u_has_tex", "u_mask", "u_cutoff")]
        self._tex_parameteri = None

    # -- scene upload ---------------------------------------------------------------------------
    def upload(self, scene) -> None:
        """Build the VBO/IBO, id SSBO, textures and per-material draw list for ``scene``."""
        t0 = time.perf_counter()
        with self.ctx:
            self._release_scene()
            ctx = self.ctx
            n_tri = int(scene.triangle_count)
            self.n_triangles = n_tri
            verts = np.empty((len(scene.positions), 8), np.float32)
            verts[:, 0:3] = scene.positions
            verts[:, 3:6] = scene.normals
            verts[:, 6:8] = scene.uvs
            if n_tri == 0:
                return
            order = np.argsort(scene.triangle_material, kind="stable").astype(np.int32)
            tri_sorted = np.ascontiguousarray(scene.triangles[order], dtype=np.int32)
            mat_sorted = scene.triangle_material[order]
            vbo = ctx.buffer(verts.tobytes())
            ibo = ctx.buffer(tri_sorted.tobytes())
            ids = ctx.buffer(order.tobytes())
            vao = ctx.vertex_array(self.prog, [(vbo, "3f 3f 2f", "in_pos", "in_nrm", "in_uv")],
                                   index_buffer=ibo, index_element_size=4, skip_errors=True)
            self._vbo, self._ibo, self._ids, self._vao = vbo, ibo, ids, vao
            self._scene_objs = [vao, vbo, ibo, ids]

            self._textures = [self._make_texture(t) for t in scene.textures]

            bounds = np.flatnonzero(np.diff(mat_sorted)) + 1
            starts = np.concatenate([[0], bounds]).astype(np.int64)
            ends = np.concatenate([bounds, [n_tri]]).astype(np.int64)
            groups = []
            for s, e in zip(starts, ends):
                m = scene.materials[int(mat_sorted[s])]
                ids_g = order[s:e]
                direct = bool(ids_g[-1] - ids_g[0] == e - s - 1)  # stable sort: ascending ids
                tex = self._textures[m.base_color_texture] if m.base_color_texture >= 0 else None
                groups.append(dict(
                    start=int(s), count=int(e - s), direct=direct, id0=int(ids_g[0]),
                    cull=not m.double_sided, texture=tex,
                    base_color=diffuse_factor(m),
                    mask=m.alpha_mode == "MASK", cutoff=float(m.alpha_cutoff)))
            self._groups = groups
        self.upload_s = time.perf_counter() - t0

    def _make_texture(self, t):
        ctx = self.ctx
        h, w = t.rgba.shape[:2]
        data = np.ascontiguousarray(t.rgba, np.uint8).tobytes()   # row 0 (top) -> GL t = 0
        if t.srgb:
            tex = ctx.texture((w, h), 4, data, alignment=1, internal_format=_GL_SRGB8_ALPHA8)
        else:
            tex = ctx.texture((w, h), 4, data, alignment=1)
        tex.build_mipmaps()
        tex.filter = (self.moderngl.LINEAR_MIPMAP_LINEAR, self.moderngl.LINEAR)
        tex.repeat_x = t.wrap_s != "clamp"
        tex.repeat_y = t.wrap_t != "clamp"
        for mode, pname in ((t.wrap_s, _GL_TEXTURE_WRAP_S), (t.wrap_t, _GL_TEXTURE_WRAP_T)):
            if mode == "mirror":
                self._set_mirror(tex, pname)
        return tex

    def _set_mirror(self, tex, pname):
        if self._tex_parameteri is None:
            self._tex_parameteri = _gl_proc("glTextureParameteri", None,
                                            ctypes.c_uint, ctypes.c_uint, ctypes.c_int)
            if self._tex_parameteri is None:
                raise RuntimeError("GLPeer: glTextureParameteri unavailable; cannot set mirror wrap")
        self._tex_parameteri(tex.glo, pname, _GL_MIRRORED_REPEAT)

    def _release_scene(self):
        for obj in self._scene_objs + self._textures:
            obj.release()
        self._scene_objs, self._textures, self._groups = [], [], []
        self.n_triangles = 0

    def release(self) -> None:
        with self.ctx:
            self._release_scene()
            for obj in (self.fbo, self._att_depth, self._att_normal, self._att_albedo,
                        self._att_id, self._zbuf, self.prog):
                obj.release()

    # -- rendering ------------------------------------------------------------------------------
    def _draw(self, camera) -> None:
        """Clear and draw every material into the MRT framebuffer (no finish, no readback)."""
        mgl, ctx, prog = self.moderngl, self.ctx, self.prog
        self.fbo.use()
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        if not self._groups:
            return
        mvp = np.asarray(camera.view_projection(self.width, self.height), np.float64).astype(np.float32)
        prog["u_mvp"].write(np.ascontiguousarray(mvp.T).tobytes())
        ctx.enable_only(mgl.DEPTH_TEST)
        ctx.depth_func = "<"
        ctx.front_face = "ccw"
        ctx.cull_face = "back"
        self._ids.bind_to_storage_buffer(0)
        culling = False
        u_base, u_direct, u_id0, u_color, u_has_tex, u_mask, u_cutoff = self._uniforms
        for g in self._groups:
            if g["cull"] != culling:
                (ctx.enable if g["cull"] else ctx.disable)(mgl.CULL_FACE)
                culling = g["cull"]
            u_base.value, u_direct.value, u_id0.value = g["start"], int(g["direct"]), g["id0"]
            u_color.value = g["base_color"]
            u_mask.value, u_cutoff.value = int(g["mask"]), g["cutoff"]
            if g["texture"] is not None:
                g["texture"].use(0)
                u_has_tex.value = 1
            else:
                u_has_tex.value = 0
            self._vao.render(mgl.TRIANGLES, vertices=3 * g["count"], first=3 * g["start"])
        ctx.disable(mgl.CULL_FACE)

    def _read(self) -> dict:
        W, H, fbo = self.width, self.height, self.fbo
        raw_id = np.frombuffer(fbo.read(components=1, attachment=3, dtype="i4"), np.int32)
        tid = raw_id.reshape(H, W)[::-1] - 1
        depth = np.frombuffer(fbo.read(components=1, attachment=0, dtype="f4"), np.float32)
        depth = depth.reshape(H, W)[::-1].copy()
        depth[tid < 0] = np.inf
        normal = np.frombuffer(fbo.read(components=3, attachment=1, dtype="f4"), np.float32)
        albedo = np.frombuffer(fbo.read(components=3, attachment=2, dtype="f4"), np.float32)
        return {
            "depth": depth,
            "normal": np.ascontiguousarray(normal.reshape(H, W, 3)[::-1]),
            "albedo": np.ascontiguousarray(albedo.reshape(H, W, 3)[::-1]),
            "triangle_id": np.ascontiguousarray(tid, dtype=np.int32),
        }

    def render(self, camera) -> dict:
        """Draw and read back the G-buffer (row 0 = top). See the module docstring for keys."""
        with self.ctx:
            self._draw(camera)
            return self._read()

    def time_frame(self, camera, repeats: int = 10, warmup: int = 3) -> list[float]:
        """Wall-clock ms per frame: clear + draw of all MRTs + glFinish, no readback."""
        with self.ctx:
            for _ in range(max(0, warmup)):
                self._draw(camera)
                self.ctx.finish()
            times = []
            for _ in range(int(repeats)):
                t0 = time.perf_counter()
                self._draw(camera)
                self.ctx.finish()
                times.append((time.perf_counter() - t0) * 1e3)
            return times

    def time_frame_with_readback(self, camera, repeats: int = 10, warmup: int = 3, read=None) -> list[float]:
        """Wall-clock ms per frame: draw + finish + readback to numpy (`read`, default: all four
        targets)."""
        read = read or self._read
        with self.ctx:
            for _ in range(max(0, warmup)):
                self._draw(camera)
                read()
            times = []
            for _ in range(int(repeats)):
                t0 = time.perf_counter()
                self._draw(camera)
                self.ctx.finish()
                read()
                times.append((time.perf_counter() - t0) * 1e3)
            return times

    def info(self) -> dict:
        return {
            "renderer": self.renderer,
            "gl_version": str(self.ctx.info.get("GL_VERSION", "?")),
            "size": [self.width, self.height],
            "triangles": self.n_triangles,
            "draw_calls": len(self._groups),
            "draws_with_id_lookup": sum(not g["direct"] for g in self._groups),
            "textures": len(self._textures),
            "upload_s": self.upload_s,
        }


# -- comparison ---------------------------------------------------------------------------------
def compare_gbuffers(a: dict, b: dict, depth_rel_tol: float = 1e-3) -> dict:
    """Agreement metrics between two G-buffers (dicts with depth/normal/albedo/triangle_id).

    Foreground is ``triangle_id >= 0``.  Relative depth difference is |da - db| / min(da, db)
    (symmetric).  Normal and albedo metrics use pixels where both have the same triangle id.
    Fractions whose pixel set is empty are NaN.
    """
    ta, tb = np.asarray(a["triangle_id"]), np.asarray(b["triangle_id"])
    if ta.shape != tb.shape:
        raise ValueError(f"G-buffer sizes differ: {ta.shape} vs {tb.shape}")
    fa, fb = ta >= 0, tb >= 0
    both, either = fa & fb, fa | fb
    n_pix = ta.size

    def frac(mask, within=None):
        denom = int(within.sum()) if within is not None else mask.size
        return float(mask.sum()) / denom if denom else float("nan")

    da = np.asarray(a["depth"], np.float64)[both]
    db = np.asarray(b["depth"], np.float64)[both]
    rel = np.abs(da - db) / np.maximum(np.minimum(da, db), 1e-30)
    depth_ok = np.zeros_like(both)
    depth_ok[both] = rel <= depth_rel_tol

    same = both & (ta == tb)
    na = np.asarray(a["normal"], np.float64)[same]
    nb = np.asarray(b["normal"], np.float64)[same]
    na /= np.maximum(np.linalg.norm(na, axis=1, keepdims=True), 1e-30)
    nb /= np.maximum(np.linalg.norm(nb, axis=1, keepdims=True), 1e-30)
    ang = np.degrees(np.arccos(np.clip(np.sum(na * nb, axis=1), -1.0, 1.0)))
    aa = np.asarray(a["albedo"], np.float64)[same]
    ab = np.asarray(b["albedo"], np.float64)[same]
    diff = aa - ab
    mse = float(np.mean(diff ** 2)) if diff.size else float("nan")
    if not diff.size:
        psnr = float("nan")
    elif mse == 0.0:
        psnr = float("inf")
    else:
        psnr = float(10.0 * np.log10(1.0 / mse))

    def pct(x, q):
        return float(np.percentile(x, q)) if x.size else float("nan")

    return {
        "pixels": int(n_pix),
        "foreground_a": int(fa.sum()),
        "foreground_b": int(fb.sum()),
        "foreground_both": int(both.sum()),
        "coverage_agreement": frac(fa == fb),
        # depth: among pixels both call foreground, and among pixels either does
        "depth_agree_frac": frac(depth_ok, both),
        "depth_agree_frac_of_either": frac(depth_ok, either),
        "depth_rel_diff_median": pct(rel, 50),
        "depth_rel_diff_p99": pct(rel, 99),
        "depth_rel_tol": float(depth_rel_tol),
        # triangle id: among pixels either calls foreground, and over the whole image
        "triangle_id_equal_frac": frac(same, either),
        "triangle_id_equal_frac_all": frac(ta == tb),
        "same_id_pixels": int(same.sum()),
        "normal_angle_median_deg": pct(ang, 50),
        "normal_angle_p99_deg": pct(ang, 99),
        "albedo_mean_abs_diff": float(np.mean(np.abs(diff))) if diff.size else float("nan"),
        "albedo_psnr_db": psnr,
    }
