/* transmission.cl: the mip chain of the opaque HDR colour that transmissive surfaces refract and
 * blur (docs/transmission.md; read by composite.cl's TRANSMISSION lookup, written once a frame by
 * clrender/passes/transmission.py before the transparent fragments are resolved).
 *
 * Algorithm: level 0 is the shaded opaque colour itself (not copied). Level l+1 has
 * ceil(w/2) × ceil(h/2) pixels; its pixel (x, y) is the 2×2 box mean of level l's pixels
 * 2x..2x+1 × 2y..2y+1, a column or row past the last one clamped to it (an odd size's last
 * pixel is then the mean of the pixels that exist). So pixel x of level l covers level-0 pixels
 * [2^l·x, 2^l·(x+1)) and a level-0 position s (pixel centre at s = x) lies at (s + 0.5)/2^l - 0.5
 * on level l. Even sizes keep the image mean exactly (up to float rounding); an odd size weights
 * its last row/column twice, as a 2×2 box must. Levels go down to 1×1; one launch per level.
 *
 * Buffers: src float[3][sw·sh] at src_offset (level l: the opaque colour, or its slice of mips),
 *          dst float[3][dw·dh] at dst_offset in mips. mips packs levels 1.. one after another,
 *          each as 3 planes (R, G, B), in the host's level table (offset in floats, w, h).
 *          src and dst may be the same buffer: a level reads only the level before it.
 * Work-groups: 2-D, one work-item per destination pixel, any shape (the host uses 8×8);
 *          no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void mip_level(global const float* src, int src_offset, int sw, int sh,
                      global float* dst, int dst_offset, int dw, int dh)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= dw || y >= dh) return;
    const int x0 = 2 * x, y0 = 2 * y;
    const int x1 = min(x0 + 1, sw - 1), y1 = min(y0 + 1, sh - 1);
    const int sn = sw * sh, dn = dw * dh;
    for (int c = 0; c < 3; ++c) {
        global const float* p = src + src_offset + c * sn;
        const float top = p[y0 * sw + x0] + p[y0 * sw + x1];
        const float bot = p[y1 * sw + x0] + p[y1 * sw + x1];
        dst[dst_offset + c * dn + y * dw + x] = (top + bot) * 0.25f;
    }
}
