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

/* Inline builtins on CPUs (VEC > 1). Pip's PoCL 3.0 (LLVM 14) compiles a kernel for the host CPU
 * (e.g. target-cpu znver3) but links its builtin library built for a generic level (haswell);
 * LLVM will not inline across different target CPUs, so every select, fmax, any... stayed an
 * out-of-line call that spills all live vectors (G-buffer resolve +58%, raster, shade +50%).
 * Written here with operators, these compute exactly PoCL's bits: select tests the mask's sign
 * bit like the ternary; fmax(a, b) = maxps(a, b) unless b is NaN (fmin likewise, clamp =
 * fmin(fmax)); fabs clears the sign; any/all test the lanes' sign bits. Only for LLVM 14 and
 * older: where PoCL's library inlines (Debian's PoCL 3.1, LLVM 15) they measured slower (raster
 * and shade +12-14%; the ternary's and/or form spills more than a select); not for SPIR compilers
 * (Intel's CPU runtime), whose backend inlines its own builtins. */
#if VEC > 1 && defined(__clang__) && !defined(__SPIR__) && __clang_major__ < 15
#define CL_OVL static inline __attribute__((overloadable, always_inline))
#undef select
#define select(a, b, c) ((c) ? (b) : (a))
/* maxps(a, b) = a > b ? a : b; PoCL's 8-wide fmax is maxps, then b where b is NaN */
#if VEC == 8 && defined(__AVX__) && __has_builtin(__builtin_ia32_maxps256)
CL_OVL floatV clr_maxps(floatV a, floatV b) { floatV m = __builtin_ia32_maxps256(a, b); return m; }
CL_OVL floatV clr_minps(floatV a, floatV b) { floatV m = __builtin_ia32_minps256(a, b); return m; }
#else
CL_OVL floatV clr_maxps(floatV a, floatV b) { return a > b ? a : b; }
CL_OVL floatV clr_minps(floatV a, floatV b) { return a < b ? a : b; }
#endif
#define CL_FMINMAX(T, S)                                                                          \
    CL_OVL T clr_fmax(T a, T b) { return b != b ? a : clr_maxps(a, b); }                         \
    CL_OVL T clr_fmin(T a, T b) { return b != b ? a : clr_minps(a, b); }                         \
    CL_OVL T clr_fmax(T a, S b) { return clr_fmax(a, (T)b); }                                    \
    CL_OVL T clr_fmin(T a, S b) { return clr_fmin(a, (T)b); }                                    \
    CL_OVL T clr_clamp(T x, T lo, T hi) { return clr_fmin(clr_fmax(x, lo), hi); }                \
    CL_OVL T clr_clamp(T x, S lo, S hi) { return clr_fmin(clr_fmax(x, (T)lo), (T)hi); }
#define CL_SFMINMAX(T)                                                                            \
    CL_OVL T clr_fmax(T a, T b) { return (a > b || b != b) ? a : b; }                            \
    CL_OVL T clr_fmin(T a, T b) { return (a < b || b != b) ? a : b; }                            \
    CL_OVL T clr_clamp(T x, T lo, T hi) { return clr_fmin(clr_fmax(x, lo), hi); }
CL_SFMINMAX(float)
#if RASTER_FP64                         /* scalar doubles must not narrow to the float overloads */
CL_SFMINMAX(double)
CL_OVL double clr_fabs(double x) { return as_double(as_ulong(x) & 0x7fffffffffffffffUL); }
#endif
CL_FMINMAX(floatV, float)
#define CL_SMINMAX(T)                                                                             \
    CL_OVL T clr_max(T a, T b) { return a > b ? a : b; }                                          \
    CL_OVL T clr_min(T a, T b) { return b < a ? b : a; }                                          \
    CL_OVL T clr_clamp(T x, T lo, T hi) { return clr_min(clr_max(x, lo), hi); }
#define CL_MINMAX(T, S) CL_SMINMAX(T)                                                          \
    CL_OVL T clr_max(T a, S b) { return clr_max(a, (T)b); }                                      \
    CL_OVL T clr_min(T a, S b) { return clr_min(a, (T)b); }                                      \
    CL_OVL T clr_clamp(T x, S lo, S hi) { return clr_min(clr_max(x, (T)lo), (T)hi); }
CL_SMINMAX(int) CL_SMINMAX(uint) CL_SMINMAX(long) CL_SMINMAX(ulong)
CL_MINMAX(intV, int) CL_MINMAX(uintV, uint)
CL_OVL float clr_fabs(float x) { return as_float(as_uint(x) & 0x7fffffffu); }
CL_OVL floatV clr_fabs(floatV x) { return as_floatV(as_uintV(x) & 0x7fffffffu); }
/* any / all: the lanes folded by | / & down to one, its sign bit */
#if VEC == 16
#define CL_LANES_FOLD(name, op) CL_OVL int name(intV m) { \
    int8 t8 = m.lo op m.hi; int4 t4 = t8.lo op t8.hi; int2 t2 = t4.lo op t4.hi; return (t2.x op t2.y) < 0; }
#elif VEC == 8
#define CL_LANES_FOLD(name, op) CL_OVL int name(intV m) { \
    int4 t4 = m.lo op m.hi; int2 t2 = t4.lo op t4.hi; return (t2.x op t2.y) < 0; }
#else
#define CL_LANES_FOLD(name, op) CL_OVL int name(intV m) { \
    int2 t2 = m.lo op m.hi; return (t2.x op t2.y) < 0; }
#endif
CL_LANES_FOLD(clr_any, |)
CL_LANES_FOLD(clr_all, &)
/* vloadN/vstoreN: a plain vector access at element alignment (one unaligned move). Every element
 * type has its overload: C overloading would otherwise convert a mismatched pointer silently. */
#define CL_VLS_AS(T, N, AS)                                                                       \
    CL_OVL T##N clr_vload##N(size_t i, AS const T* p) { return *(AS const T##N##_u*)(p + i * N); } \
    CL_OVL void clr_vstore##N(T##N v, size_t i, AS T* p) { *(AS T##N##_u*)(p + i * N) = v; }
#define CL_VLS(T, N)                                                                              \
    typedef T##N T##N##_u __attribute__((aligned(sizeof(T))));                                   \
    CL_VLS_AS(T, N, global) CL_VLS_AS(T, N, local) CL_VLS_AS(T, N, private)                       \
    CL_OVL T##N clr_vload##N(size_t i, constant T* p) { return *(constant T##N##_u*)(p + i * N); }
#define CL_VLS_T(T) CL_VLS(T, 2) CL_VLS(T, 4) CL_VLS(T, 8) CL_VLS(T, 16)
CL_VLS_T(char) CL_VLS_T(uchar) CL_VLS_T(short) CL_VLS_T(ushort) CL_VLS_T(int) CL_VLS_T(uint)
CL_VLS_T(long) CL_VLS_T(ulong) CL_VLS_T(float)
#if RASTER_FP64
CL_VLS_T(double)
#endif
/* floor and (correctly rounded) sqrt as the LLVM operations PoCL's library calls wrap. */
#if __has_builtin(__builtin_elementwise_floor)
CL_OVL float clr_floor(float x) { return __builtin_elementwise_floor(x); }
CL_OVL floatV clr_floor(floatV x) { return __builtin_elementwise_floor(x); }
#if RASTER_FP64
CL_OVL double clr_floor(double x) { return __builtin_elementwise_floor(x); }
#endif
#undef floor
#define floor clr_floor
#endif
#if VEC == 8 && defined(__AVX__) && __has_builtin(__builtin_ia32_sqrtps256)
CL_OVL float clr_sqrt(float x) { return __builtin_sqrtf(x); }
CL_OVL floatV clr_sqrt(floatV x) { return __builtin_ia32_sqrtps256(x); }
#if RASTER_FP64
CL_OVL double clr_sqrt(double x) { return __builtin_sqrt(x); }
#endif
#undef sqrt
#define sqrt clr_sqrt
#endif
#undef vloadV                           /* CAT(vload, VEC) expands PoCL's vload macro first */
#undef vstoreV
#define vloadV CAT(clr_vload, VEC)
#define vstoreV CAT(clr_vstore, VEC)
#undef vload2
#undef vload4
#undef vload8
#undef vload16
#undef vstore2
#undef vstore4
#undef vstore8
#undef vstore16
#define vload2 clr_vload2
#define vload4 clr_vload4
#define vload8 clr_vload8
#define vload16 clr_vload16
#define vstore2 clr_vstore2
#define vstore4 clr_vstore4
#define vstore8 clr_vstore8
#define vstore16 clr_vstore16
#undef fmax
#undef fmin
#undef clamp
#undef max
#undef min
#undef fabs
#undef any
#undef all
#define fmax clr_fmax
#define fmin clr_fmin
#define clamp clr_clamp
#define max clr_max
#define min clr_min
#define fabs clr_fabs
#define any clr_any
#define all clr_all
#endif

#endif
