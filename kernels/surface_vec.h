/* surface_vec.h: a visible prim's surface at a run of VEC pixels, one prim per lane (the
 * G-buffer resolve of opaque pixels, gbuffer.cl, and the forward shading of transparent
 * fragments, forward.h, so both see exactly the same surface).
 *
 * surface_at(): per lane, the prim's 64-bit edge functions at the pixel center and at its right
 * and lower neighbours give perspective-correct barycentrics in the input triangle and their
 * screen derivatives (docs/raster_contract.md §5); from them the interpolated vertex normal
 * (geometric where that degenerates; unit; flipped on back faces), the base colour and alpha
 * (material factor × trilinear texture: GL's LOD from the UV derivatives, texels gathered per
 * lane, filtering in linear space) and the material's specular terms. Lanes outside `fg` read
 * prim 0 / texel 0 and must be masked by the caller.
 */
#ifndef CLRENDER_SURFACE_VEC_H
#define CLRENDER_SURFACE_VEC_H
#include "structs.h"
#include "vec.h"

#ifndef SURFACE_TEXTURES
#define SURFACE_TEXTURES 1        /* 0: base colour = material factor only, no texture read */
#endif

typedef struct { floatV x, y, z; } vec3V;

static inline floatV dot3V(vec3V a, vec3V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

/* Gathers a float3 attribute of vertex idx[l] for every lane. */
static inline vec3V gather3(global const float* a, intV idx)
{
    intV i3 = idx * 3;
    vec3V r = { GATHER_F(a, i3), GATHER_F(a, i3 + 1), GATHER_F(a, i3 + 2) };
    return r;
}

static inline vec3V interp3(vec3V a, vec3V b, vec3V c, floatV b0, floatV b1, floatV b2)
{
    vec3V r = { b0 * a.x + b1 * b.x + b2 * c.x, b0 * a.y + b1 * b.y + b2 * c.y, b0 * a.z + b1 * b.z + b2 * c.z };
    return r;
}

/* Texture coordinate folded into one period: repeat [0,1), mirror/clamp [0,1]. */
static inline floatV foldV(floatV u, intV mode)
{
    u = fmin(fmax(u, -1.0e9f), 1.0e9f);     /* NaN -> -1e9 (fmax ignores NaN) */
    floatV rep = u - floor(u);
    floatV t = u - 2.0f * floor(u * 0.5f);
    floatV mir = select(t, 2.0f - t, t > 1.0f);
    floatV clm = clamp(u, (floatV)0.0f, (floatV)1.0f);
    return select(select(clm, mir, mode == WRAP_MIRROR), rep, mode == WRAP_REPEAT);
}

static inline intV wrap_edgeV(intV i, intV size, intV mode)
{
    intV rep = select(select(i, (intV)0, i >= size), size - 1, i < 0);
    return select(clamp(i, (intV)0, size - 1), rep, mode == WRAP_REPEAT);
}

typedef struct { floatV r, g, b, a; } rgbaV;

/* Bilinear sample of per-lane mip levels (offset/width/height) at folded coordinates. */
static rgbaV bilinearV(global const uint* texels, constant float* lut, intV active,
                       intV offset, intV width, intV height, intV wrap_s, intV wrap_t, floatV u, floatV v)
{
    floatV fx = foldV(u, wrap_s) * convert_floatV(width) - 0.5f;
    floatV fy = foldV(v, wrap_t) * convert_floatV(height) - 0.5f;
    intV x0 = convert_intV(fx + 1.0f) - 1, y0 = convert_intV(fy + 1.0f) - 1;   /* floor, fx >= -0.5 */
    floatV ax = fx - convert_floatV(x0), ay = fy - convert_floatV(y0);
    intV xa = wrap_edgeV(x0, width, wrap_s), xb = wrap_edgeV(x0 + 1, width, wrap_s);
    intV ya = wrap_edgeV(y0, height, wrap_t), yb = wrap_edgeV(y0 + 1, height, wrap_t);
    intV idx[4] = { offset + ya * width + xa, offset + ya * width + xb,
                    offset + yb * width + xa, offset + yb * width + xb };
    rgbaV t[4];
    for (int k = 0; k < 4; ++k) {
        intV i = select((intV)0, idx[k], active);          /* inactive lanes read texel 0 */
        uintV w = GATHER_U(texels, i);
        intV c0 = as_intV(w & 255u), c1 = as_intV((w >> 8) & 255u), c2 = as_intV((w >> 16) & 255u);
        t[k].r = GATHER_F(lut, c0);
        t[k].g = GATHER_F(lut, c1);
        t[k].b = GATHER_F(lut, c2);
        t[k].a = convert_floatV(w >> 24) * (1.0f / 255.0f);
    }
    rgbaV r;
#define BILERP(c) { floatV top = t[0].c + (t[1].c - t[0].c) * ax, bot = t[2].c + (t[3].c - t[2].c) * ax; \
                    r.c = top + (bot - top) * ay; }
    BILERP(r) BILERP(g) BILERP(b) BILERP(a)
#undef BILERP
    return r;
}

/* Per-lane mip level record `level` of texture `tex`. */
static inline void gather_level(global const TexLevel* levels, intV level, intV* offset, intV* w, intV* h)
{
    *offset = GATHER_M(intV, levels, level, offset);
    *w = GATHER_M(intV, levels, level, width);
    *h = GATHER_M(intV, levels, level, height);
}

static inline floatV fast_log2V(floatV x)   /* exponent + linear mantissa, as texture units do */
{
    intV bits = as_intV(x);
    return convert_floatV((bits >> 23) - 127) + (as_floatV((bits & 0x007fffff) | 0x3f800000) - 1.0f);
}

/* The scene buffers a surface is evaluated from. */
typedef struct {
    global const Prim* prims;
    global const float* positions;
    global const float* normals;
    global const float* uvs;
    global const int* triangles;
    global const Material* materials;
    global const uint* texels;
    constant float* srgb_lut;
    global const TexInfo* tex_infos;
    global const TexLevel* tex_levels;
} SceneV;

typedef struct {
    intV tri, flags, mat;
    intV i0, i1, i2;            /* the triangle's vertex indices */
    floatV c0, c1, c2;          /* barycentrics of the pixel center in the input triangle */
    vec3V n;                    /* unit normal, flipped on back faces */
    floatV r, g, b, a;          /* linear base colour × texture; alpha = factor alpha × texture alpha */
    floatV spec_i, spec_p;
} SurfaceV;

/* The surfaces of prims w (per lane; lanes outside fg: any valid index) at pixels (px, py),
 * evaluated at the fixed-point point (256 px + 128 + ox, 256 py + 128 + oy) of the prims' frame:
 * the pixel centre for (0, 0); (-dx, -dy) for prims set up for sub-sample (dx, dy) (the raster
 * contract §10), whose frame is shifted by it, evaluates them at the pixel centre again, as
 * multisampling shades once per pixel. */
static SurfaceV surface_at_offset(const SceneV* sc, intV w, intV fg, intV px, intV py, int ox, int oy)
{
    global const Prim* prims = sc->prims;
    global const float* positions = sc->positions;
    global const float* normals = sc->normals;
    global const float* uvs = sc->uvs;
    global const int* triangles = sc->triangles;
    global const Material* materials = sc->materials;
    global const uint* texels = sc->texels;
    constant float* srgb_lut = sc->srgb_lut;
    global const TexInfo* tex_infos = sc->tex_infos;
    global const TexLevel* tex_levels = sc->tex_levels;
    SurfaceV sf;
#define PRIM_I(m) GATHER_M(intV, prims, w, m)
#define PRIM_F(m) GATHER_M(floatV, prims, w, m)
    longV X0 = CONVERT_V(PRIM_I(x[0]), longV), X1 = CONVERT_V(PRIM_I(x[1]), longV), X2 = CONVERT_V(PRIM_I(x[2]), longV);
    longV Y0 = CONVERT_V(PRIM_I(y[0]), longV), Y1 = CONVERT_V(PRIM_I(y[1]), longV), Y2 = CONVERT_V(PRIM_I(y[2]), longV);
    intV tri = PRIM_I(tri), flags = as_intV(GATHER_M(uintV, prims, w, flags)), mat = PRIM_I(material);
    floatV iw0 = PRIM_F(inv_w[0]), iw1 = PRIM_F(inv_w[1]), iw2 = PRIM_F(inv_w[2]);
    floatV b10 = PRIM_F(bary1[0]), b11 = PRIM_F(bary1[1]), b12 = PRIM_F(bary1[2]);
    floatV b20 = PRIM_F(bary2[0]), b21 = PRIM_F(bary2[1]), b22 = PRIM_F(bary2[2]);
#undef PRIM_I
#undef PRIM_F

    {
        /* Edge functions at the pixel center (docs/raster_contract.md §5), 64-bit. */
        longV SX = CONVERT_V(px, longV) * 256 + (128 + ox), SY = CONVERT_V(py, longV) * 256 + (128 + oy);
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
        floatV c1, c2, c1x, c2x, c1y, c2y;
        BARY(e0, e1, e2, c1, c2)
        BARY(e0 - dy0 * 256, e1 - dy1 * 256, e2 - dy2 * 256, c1x, c2x)
        BARY(e0 + dx0 * 256, e1 + dx1 * 256, e2 + dx2 * 256, c1y, c2y)
#undef BARY
        floatV c0 = 1.0f - c1 - c2;
        c0 = select((floatV)0.0f, c0, fg); c1 = select((floatV)0.0f, c1, fg); c2 = select((floatV)0.0f, c2, fg);

        intV t3 = tri * 3;
        intV i0 = GATHER_I(triangles, t3), i1 = GATHER_I(triangles, t3 + 1), i2 = GATHER_I(triangles, t3 + 2);

        /* Normal: interpolated vertex normal, geometric where that degenerates. */
        vec3V n = interp3(gather3(normals, i0), gather3(normals, i1), gather3(normals, i2), c0, c1, c2);
        intV degenerate = fg & !(dot3V(n, n) > 1e-20f);
        if (ANY(degenerate)) {
            vec3V p0 = gather3(positions, i0), p1 = gather3(positions, i1), p2 = gather3(positions, i2);
            vec3V a = { p1.x - p0.x, p1.y - p0.y, p1.z - p0.z }, b = { p2.x - p0.x, p2.y - p0.y, p2.z - p0.z };
            vec3V g = { a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x };
            n.x = select(n.x, g.x, degenerate); n.y = select(n.y, g.y, degenerate); n.z = select(n.z, g.z, degenerate);
        }
        floatV len2 = dot3V(n, n);
        intV zero = !(len2 > 0.0f);
        n.z = select(n.z, (floatV)1.0f, zero);
        floatV inv_len = select(rsqrt(len2), (floatV)1.0f, zero);
        inv_len = select(inv_len, -inv_len, (flags & (int)PRIM_BACKFACE) != 0);
        n.x *= inv_len; n.y *= inv_len; n.z *= inv_len;

        /* Material terms, per lane. */
        floatV ca = GATHER_M(floatV, materials, mat, base_color[3]);
        floatV cr = GATHER_M(floatV, materials, mat, base_color[0]);
        floatV cg = GATHER_M(floatV, materials, mat, base_color[1]);
        floatV cb = GATHER_M(floatV, materials, mat, base_color[2]);
#if SURFACE_TEXTURES
        intV tex = select((intV)-1, GATHER_M(intV, materials, mat, texture), fg);
#else
        intV tex = (intV)-1;            /* the base colour's texture is not needed (thin G-buffer) */
#endif
        floatV spec_i = GATHER_M(floatV, materials, mat, spec_intensity);
        floatV spec_p = GATHER_M(floatV, materials, mat, spec_power);

        intV textured = tex >= 0;
#if VEC == 1
        textured = textured ? 1 : 0;
#endif
        if (ANY(textured)) {
            /* UVs at the pixel and its neighbours -> GL's LOD, then trilinear. */
            floatV u0 = GATHER_F(uvs, 2 * i0), v0 = GATHER_F(uvs, 2 * i0 + 1);
            floatV u1 = GATHER_F(uvs, 2 * i1), v1 = GATHER_F(uvs, 2 * i1 + 1);
            floatV u2 = GATHER_F(uvs, 2 * i2), v2 = GATHER_F(uvs, 2 * i2 + 1);
            floatV u = c0 * u0 + c1 * u1 + c2 * u2, v = c0 * v0 + c1 * v1 + c2 * v2;
            floatV dux = (c1x - c1) * (u1 - u0) + (c2x - c2) * (u2 - u0);
            floatV dvx = (c1x - c1) * (v1 - v0) + (c2x - c2) * (v2 - v0);
            floatV duy = (c1y - c1) * (u1 - u0) + (c2y - c2) * (u2 - u0);
            floatV dvy = (c1y - c1) * (v1 - v0) + (c2y - c2) * (v2 - v0);

            intV ti = max(tex, 0);
            intV first = GATHER_M(intV, tex_infos, ti, first_level), nlev = GATHER_M(intV, tex_infos, ti, levels);
            intV wrap_s = GATHER_M(intV, tex_infos, ti, wrap_s), wrap_t = GATHER_M(intV, tex_infos, ti, wrap_t);
            intV off0, w0, h0;
            gather_level(tex_levels, first, &off0, &w0, &h0);
            floatV fw = convert_floatV(w0), fh = convert_floatV(h0);
            floatV rho2 = fmax((dux * fw) * (dux * fw) + (dvx * fh) * (dvx * fh),
                               (duy * fw) * (duy * fw) + (dvy * fh) * (dvy * fh));
            rho2 = fmin(fmax(rho2, 1e-20f), 1e30f);   /* NaN -> 1e-20: a finite LOD */
            floatV lod = fmin(fmax(0.5f * fast_log2V(rho2), 0.0f), convert_floatV(nlev - 1));
            intV l0 = convert_intV(lod), l1 = min(l0 + 1, nlev - 1);
            floatV f = lod - convert_floatV(l0);
            intV offa, wa, ha, offb, wb, hb;
            gather_level(tex_levels, first + l0, &offa, &wa, &ha);
            gather_level(tex_levels, first + l1, &offb, &wb, &hb);
            rgbaV ta = bilinearV(texels, srgb_lut, textured, offa, wa, ha, wrap_s, wrap_t, u, v);
            rgbaV tb = bilinearV(texels, srgb_lut, textured & (f > 0.0f), offb, wb, hb, wrap_s, wrap_t, u, v);
            cr = select(cr, cr * (ta.r + (tb.r - ta.r) * f), textured);
            cg = select(cg, cg * (ta.g + (tb.g - ta.g) * f), textured);
            cb = select(cb, cb * (ta.b + (tb.b - ta.b) * f), textured);
            ca = select(ca, ca * (ta.a + (tb.a - ta.a) * f), textured);
        }
        sf.tri = tri; sf.flags = flags; sf.mat = mat; sf.i0 = i0; sf.i1 = i1; sf.i2 = i2;
        sf.c0 = c0; sf.c1 = c1; sf.c2 = c2; sf.n = n;
        sf.r = cr; sf.g = cg; sf.b = cb; sf.a = ca; sf.spec_i = spec_i; sf.spec_p = spec_p;
    }
    return sf;
}

static inline SurfaceV surface_at(const SceneV* sc, intV w, intV fg, intV px, intV py)
{
    return surface_at_offset(sc, w, fg, px, py, 0, 0);
}
#endif

