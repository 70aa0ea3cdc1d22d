/* _template.cl: a copyable minimal kernel for a new pass (clrender/passes/_template.py).
 *
 * Algorithm: one work-item per pixel: the luminance of the HDR colour,
 *            Y = LUMA_R·r + LUMA_G·g + LUMA_B·b (Rec. 709 weights by default), summed in that
 *            order without contraction, so a NumPy reference in float32 matches bit for bit.
 *
 * Buffers: color float[3][W·H] (planes r, g, b: shade.cl's layout); out: luminance float[W·H].
 * Work-groups: 1-D over W·H pixels, any size (launch_1d's fixed 64: PoCL compiles once per
 *          local size); ids past W·H return. No barriers, no local memory.
 *
 * Compiles on its own: every option has a default below (the pass passes its defines).
 */
#pragma OPENCL FP_CONTRACT OFF
#ifndef LUMA_R
#define LUMA_R 0.2126f
#endif
#ifndef LUMA_G
#define LUMA_G 0.7152f
#endif
#ifndef LUMA_B
#define LUMA_B 0.0722f
#endif

kernel void luminance(global const float* color, int width, int height, global float* out)
{
    const int q = get_global_id(0), npix = width * height;
    if (q >= npix) return;
    const float r = color[q], g = color[npix + q], b = color[2 * npix + q];
    const float y = LUMA_R * r + LUMA_G * g;
    out[q] = y + LUMA_B * b;
}
