/* surface_vec.h: a visible prim's surface at a run of VEC pixels, one prim per lane (the
 * G-buffer resolve of opaque pixels, gbuffer.cl, and the forward shading of transparent
 * fragments, forward.h, so both see exactly the same surface).
 *
 * surface_at(): per lane, the prim's 64-bit edge functions at the pixel center and at its right
 * and lower neighbours give perspective-correct barycentrics in the input triangle and their
 * screen derivatives (docs/raster_contract.md §5); from them the interpolated vertex normal
 * (geometric where that degenerates; unit), then the material (material_eval.h, docs/materials.md:
 * base colour, metallic-roughness, normal map, occlusion, emissive), and last the flip of the
 * normal on back faces. Lanes outside `fg` read prim 0 / texel 0 and must be masked by the caller.
 */
#ifndef CLRENDER_SURFACE_VEC_H
#define CLRENDER_SURFACE_VEC_H
#include "structs.h"
#include "vec.h"
#include "texture_vec.h"

#include "surface_types.h"
#include "material_eval.h"

#ifndef ORTHO
#define ORTHO 0                 /* 1: orthographic prims (setup.cl): inv_w hold depths, barycentrics are screen-linear */
#endif

/* The geometry of prims w (per lane; lanes outside fg: any valid index) at the centres of pixels
 * (px, py) (fixed point 256 px + 128, 256 py + 128): sf's ids, barycentrics and unit interpolated
 * normal (not flipped, no normal map), and the barycentrics with their derivatives in *bary_out. */
static inline void prim_geometry(const SceneV* sc, intV w, intV fg, intV px, intV py, SurfaceV* sf_out,
                                 BaryV* bary_out)
{
    global const Prim* prims = sc->prims;
    SurfaceV sf;
    BaryV bc;
#define PRIM_I(m) GATHER_MS(intV, prims, w, m)
#define PRIM_F(m) GATHER_MS(floatV, prims, w, m)
    longV X0 = CONVERT_V(PRIM_I(x[0]), longV), X1 = CONVERT_V(PRIM_I(x[1]), longV), X2 = CONVERT_V(PRIM_I(x[2]), longV);
    longV Y0 = CONVERT_V(PRIM_I(y[0]), longV), Y1 = CONVERT_V(PRIM_I(y[1]), longV), Y2 = CONVERT_V(PRIM_I(y[2]), longV);
    intV tri = PRIM_I(tri), flags = as_intV(GATHER_MS(uintV, prims, w, flags)), mat = PRIM_I(material);
#if ORTHO
    const floatV iw0 = 1.0f, iw1 = 1.0f, iw2 = 1.0f;
#else
    floatV iw0 = PRIM_F(inv_w[0]), iw1 = PRIM_F(inv_w[1]), iw2 = PRIM_F(inv_w[2]);
#endif
    floatV b10 = PRIM_F(bary1[0]), b11 = PRIM_F(bary1[1]), b12 = PRIM_F(bary1[2]);
    floatV b20 = PRIM_F(bary2[0]), b21 = PRIM_F(bary2[1]), b22 = PRIM_F(bary2[2]);
#undef PRIM_I
#undef PRIM_F

    /* Edge functions at the pixel center (docs/raster_contract.md §5), 64-bit. */
    longV SX = CONVERT_V(px, longV) * 256 + 128, SY = CONVERT_V(py, longV) * 256 + 128;
    longV dx0 = X1 - X0, dy0 = Y1 - Y0, dx1 = X2 - X1, dy1 = Y2 - Y1, dx2 = X0 - X2, dy2 = Y0 - Y2;
    longV e0 = dx0 * (SY - Y0) - dy0 * (SX - X0);
    longV e1 = dx1 * (SY - Y1) - dy1 * (SX - X1);
    longV e2 = dx2 * (SY - Y2) - dy2 * (SX - X2);

    /* Perspective-correct barycentrics in the input triangle at (e0,e1,e2) and at the
     * neighbours one pixel right (e - dy·256) and one pixel down (e + dx·256). */
#define BARY(E0, E1, E2, B1, B2) { \
        floatV w0 = CONVERT_V(E1, floatV) * iw0, w1 = CONVERT_V(E2, floatV) * iw1, w2 = CONVERT_V(E0, floatV) * iw2; \
        floatV inv = 1.0f / ((w0 + w1) + w2); \
        B1 = (w0 * b10 + w1 * b11 + w2 * b12) * inv; B2 = (w0 * b20 + w1 * b21 + w2 * b22) * inv; }
    floatV c1, c2;
    BARY(e0, e1, e2, c1, c2)
    BARY(e0 - dy0 * 256, e1 - dy1 * 256, e2 - dy2 * 256, bc.c1x, bc.c2x)
    BARY(e0 + dx0 * 256, e1 + dx1 * 256, e2 + dx2 * 256, bc.c1y, bc.c2y)
#undef BARY
    floatV c0 = 1.0f - c1 - c2;
    c0 = select((floatV)0.0f, c0, fg); c1 = select((floatV)0.0f, c1, fg); c2 = select((floatV)0.0f, c2, fg);
    bc.c0 = c0; bc.c1 = c1; bc.c2 = c2;

    intV t3 = tri * 3;
    bc.i0 = GATHER_IS(sc->triangles, t3); bc.i1 = GATHER_IS(sc->triangles, t3 + 1); bc.i2 = GATHER_IS(sc->triangles, t3 + 2);

    /* Normal: interpolated vertex normal, geometric where that degenerates; unit. */
    global const float* normals = sc->normals;
    vec3V n = interp3(gather3(normals, bc.i0), gather3(normals, bc.i1), gather3(normals, bc.i2), c0, c1, c2);
    intV degenerate = fg & !(dot3V(n, n) > 1e-20f);
    if (ANY(degenerate)) {
        global const float* positions = sc->positions;
        vec3V p0 = gather3(positions, bc.i0), p1 = gather3(positions, bc.i1), p2 = gather3(positions, bc.i2);
        vec3V a = { p1.x - p0.x, p1.y - p0.y, p1.z - p0.z }, b = { p2.x - p0.x, p2.y - p0.y, p2.z - p0.z };
        vec3V g = { a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x };
        n.x = select(n.x, g.x, degenerate); n.y = select(n.y, g.y, degenerate); n.z = select(n.z, g.z, degenerate);
    }
    floatV len2 = dot3V(n, n);
    intV zero = !(len2 > 0.0f);
    n.z = select(n.z, (floatV)1.0f, zero);
    floatV inv_len = select(RSQRT(len2), (floatV)1.0f, zero);
    n.x *= inv_len; n.y *= inv_len; n.z *= inv_len;

    sf.tri = tri; sf.flags = flags; sf.mat = mat; sf.i0 = bc.i0; sf.i1 = bc.i1; sf.i2 = bc.i2;
    sf.c0 = c0; sf.c1 = c1; sf.c2 = c2; sf.n = n;
    *sf_out = sf;
    *bary_out = bc;
}

/* The surfaces of prims w at the centres of pixels (px, py) (prim_geometry, then the material);
 * their barycentrics go to *bary_out (layer_shading.h samples the layer textures with them). */
static SurfaceV surface_bary_at(const SceneV* sc, intV w, intV fg, intV px, intV py, BaryV* bary_out)
{
    SurfaceV sf;
    BaryV bc;
    prim_geometry(sc, w, fg, px, py, &sf, &bc);
    const intV flags = sf.flags;
    evaluate_material(sc, &bc, fg, &sf);            /* material_eval.h: colours, specular, normal map */

    const intV back = (flags & (int)PRIM_BACKFACE) != 0;     /* the glTF rule: flip before lighting */
    sf.n.x = select(sf.n.x, -sf.n.x, back); sf.n.y = select(sf.n.y, -sf.n.y, back);
    sf.n.z = select(sf.n.z, -sf.n.z, back);
    *bary_out = bc;
    return sf;
}

static inline SurfaceV surface_at(const SceneV* sc, intV w, intV fg, intV px, intV py)
{
    BaryV bc;
    return surface_bary_at(sc, w, fg, px, py, &bc);
}
#endif
