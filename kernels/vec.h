/* vec.h: VEC-wide vector types for kernels that process VEC pixels per work-item.
 * VEC = 1 on GPUs (one pixel per work-item, the hardware vectorizes across work-items);
 * 8 or 16 on CPUs, where PoCL cannot vectorize across work-items through loops or library
 * calls, so kernels use explicit vectors. Comparisons yield masks: -1/0 for vectors and 1/0
 * for scalars, and both work with `select` and the ANY() macro below. */
#ifndef CLRENDER_VEC_H
#define CLRENDER_VEC_H

#ifndef VEC
#define VEC 8
#endif

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)

#if VEC == 1
typedef int intV;
typedef uint uintV;
typedef long longV;
typedef float floatV;
#define LANES ((intV)0)
#define convert_intV(x) ((int)(x))
#define convert_uintV(x) ((uint)(x))
#define convert_floatV(x) ((float)(x))
#define convert_longV(x) ((long)(x))
#define ANY(m) (m)
#define LANE_I(v, i) (v)
#define LANE_F(v, i) (v)
#define LANE_L(v, i) (v)
#define as_intV(x) as_int(x)
#define as_uintV(x) as_uint(x)
#define as_floatV(x) as_float(x)
#define vloadV(i, p) ((p)[i])
#define vstoreV(v, i, p) ((p)[i] = (v))
#define vstore_halfV(v, i, p) vstore_half_rte((v), (i), (p))
#define vload_halfV(i, p) vload_half((i), (p))
#else
typedef CAT(int, VEC) intV;
typedef CAT(uint, VEC) uintV;
typedef CAT(long, VEC) longV;
typedef CAT(float, VEC) floatV;
#if VEC == 4
#define LANES ((intV)(0, 1, 2, 3))
#elif VEC == 8
#define LANES ((intV)(0, 1, 2, 3, 4, 5, 6, 7))
#elif VEC == 16
#define LANES ((intV)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15))
#else
#error "VEC must be 1, 4, 8 or 16"
#endif
#define convert_intV CAT(convert_int, VEC)
#define convert_uintV CAT(convert_uint, VEC)
#define convert_floatV CAT(convert_float, VEC)
#define convert_longV CAT(convert_long, VEC)
#define ANY(m) any(m)
/* Lane access through the vector's storage (private memory). */
#define LANE_I(v, i) (((int*)&(v))[i])
#define LANE_F(v, i) (((float*)&(v))[i])
#define LANE_L(v, i) (((long*)&(v))[i])
#define as_intV CAT(as_int, VEC)
#define as_uintV CAT(as_uint, VEC)
#define as_floatV CAT(as_float, VEC)
#define vloadV CAT(vload, VEC)
#define vstoreV CAT(vstore, VEC)
#define vstore_halfV CAT(CAT(vstore_half, VEC), _rte)
#define vload_halfV CAT(vload_half, VEC)
#endif

/* CONVERT_V(x, T): vector conversion with round-to-nearest-even, like convert_T. Clang's
 * builtin is a plain inline LLVM cast; PoCL's convert_T for 64-bit-lane vectors (long8,
 * double8) is an out-of-line library call whose cost dominated raster.cl's 64-bit path. */
#if VEC > 1 && defined(__clang__) && defined(__has_builtin)
#if __has_builtin(__builtin_convertvector)
#define CONVERT_V(x, T) __builtin_convertvector((x), T)
#endif
#endif
#ifndef CONVERT_V
#define CONVERT_V(x, T) CAT(convert_, T)(x)
#endif

/* RASTER_FP64: raster.cl may evaluate large edge functions as exact doubles (integers below
 * 2^53) on CPUs, where double vectors convert to float natively and 64-bit integer vectors do
 * not. Off for VEC = 1 (GPUs: slow doubles) and on devices without cl_khr_fp64. */
#if VEC > 1 && defined(cl_khr_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#define RASTER_FP64 1
typedef CAT(double, VEC) doubleV;
#define convert_doubleV CAT(convert_double, VEC)
#else
#define RASTER_FP64 0
#endif

/* GATHER_F/I/U(p, idx): a vector of p[idx lane by lane], written as a vector literal so the
 * compiler can emit a hardware gather instead of lane-by-lane stores into memory. */
#if VEC == 1
#define GATHER_T(T, p, i) ((T)(p)[i])
#elif VEC == 4
#define GATHER_T(T, p, i) ((T)((p)[(i).s0], (p)[(i).s1], (p)[(i).s2], (p)[(i).s3]))
#elif VEC == 8
#define GATHER_T(T, p, i) ((T)((p)[(i).s0], (p)[(i).s1], (p)[(i).s2], (p)[(i).s3], \
                               (p)[(i).s4], (p)[(i).s5], (p)[(i).s6], (p)[(i).s7]))
#else
#define GATHER_T(T, p, i) ((T)((p)[(i).s0], (p)[(i).s1], (p)[(i).s2], (p)[(i).s3], \
                               (p)[(i).s4], (p)[(i).s5], (p)[(i).s6], (p)[(i).s7], \
                               (p)[(i).s8], (p)[(i).s9], (p)[(i).sa], (p)[(i).sb], \
                               (p)[(i).sc], (p)[(i).sd], (p)[(i).se], (p)[(i).sf]))
#endif
/* GATHER_M(T, p, i, m): a vector of the member m of structs p[i] (e.g. x[0] of a Prim). */
#if VEC == 1
#define GATHER_M(T, p, i, m) ((T)(p)[i].m)
#elif VEC == 4
#define GATHER_M(T, p, i, m) ((T)((p)[(i).s0].m, (p)[(i).s1].m, (p)[(i).s2].m, (p)[(i).s3].m))
#elif VEC == 8
#define GATHER_M(T, p, i, m) ((T)((p)[(i).s0].m, (p)[(i).s1].m, (p)[(i).s2].m, (p)[(i).s3].m, \
                                  (p)[(i).s4].m, (p)[(i).s5].m, (p)[(i).s6].m, (p)[(i).s7].m))
#else
#define GATHER_M(T, p, i, m) ((T)((p)[(i).s0].m, (p)[(i).s1].m, (p)[(i).s2].m, (p)[(i).s3].m, \
                                  (p)[(i).s4].m, (p)[(i).s5].m, (p)[(i).s6].m, (p)[(i).s7].m, \
                                  (p)[(i).s8].m, (p)[(i).s9].m, (p)[(i).sa].m, (p)[(i).sb].m, \
                                  (p)[(i).sc].m, (p)[(i).sd].m, (p)[(i).se].m, (p)[(i).sf].m))
#endif
#define GATHER_F(p, i) GATHER_T(floatV, p, i)
#define GATHER_I(p, i) GATHER_T(intV, p, i)
#define GATHER_U(p, i) GATHER_T(uintV, p, i)

/* RSQRT(x): 1 / sqrt(x), for every reciprocal square root in the kernels. Division and sqrt are
 * correctly rounded on every implementation clrender runs on (the build option where offered;
 * Intel's CPU runtime, which does not advertise it, measured exact), so every implementation
 * computes the same bits. rsqrt() may be off by 2 ulp, and its bits differ: PoCL computes
 * 1 / sqrt, Intel's CPU runtime another rounding in its scalar and 16-wide builds (1 ulp apart
 * on 23% of inputs), which moved G-buffer normals by a 12-bit code between implementations. */
#define RSQRT(x) (1.0f / sqrt(x))

#endif
