// The fused splat's GPU kernels, compiled at run time by NVRTC (see mod.rs).
//
// The arithmetic is the CPU kernel's (src/render/splat/kernel.rs): a Gaussian footprint
// g = (exp(-d²/2σ²) − ε)/(1 − ε) per supersampled pixel within radius·σ, blended as coverage
// (I = 1 − Π(1 − α), α = min(α_max, g)) or additive density (I = Σ g), then s×s average
// pooling; the reverse pass pulls ∂L/∂image back to ∂L/∂(u, v) per point.
//
// Deterministic: the forward pass accumulates log(1 − α) (coverage) or g (additive) per
// supersampled pixel in 64-bit fixed point with integer atomics, which are associative, so
// the sum does not depend on the order the threads arrive in. The reverse pass gives each
// point one warp that sums its own footprint and reduces in a fixed tree: no atomics.
//
// One warp per point: its lanes take the footprint's pixels in turn (at the paper's σ = 2.5
// and radius 3 a footprint is 16×16 supersampled pixels, 8 per lane).

// Fixed-point scale of the accumulators: 2^40 (a quantum of 9.1e-13).
#define FX_SCALE 1099511627776.0
#define FX_INV (1.0 / 1099511627776.0)
// Transmittance below this is exactly 0 (the CPU kernel's TRANSMITTANCE_FLOOR).
#define TRANS_FLOOR 1e-20
// Below this log-transmittance a pixel is covered for good (exp(-60) < TRANS_FLOOR): further
// terms are skipped, which bounds the accumulator far inside 64 bits without changing the
// result (the pixel's transmittance is 0 either way).
#define LOG_T_STOP (-60.0 * FX_SCALE)

__device__ __forceinline__ float ex(float x) { return expf(x); }
__device__ __forceinline__ double ex(double x) { return exp(x); }

// Inclusive pixel range whose centres lie within r of x, clipped to [0, n): the CPU's
// `footprint`. Non-finite x fails the first comparison.
__device__ __forceinline__ bool footprint(double x, double r, int n, int* lo, int* hi) {
    if (!(x + r > 0.0 && x - r < (double)n)) return false;
    int l = (int)ceil(x - r - 0.5);
    int h = (int)floor(x + r - 0.5);
    if (l < 0) l = 0;
    if (h > n - 1) h = n - 1;
    *lo = l;
    *hi = h;
    return l <= h;
}

template <typename T>
__device__ void forward_impl(const T* __restrict__ uv, int n, long long* __restrict__ acc,
                             int gw, int gh, int coverage, double r, double inv2s2, double eps,
                             double inv1me, double amax) {
    const long long p = ((long long)blockIdx.x * blockDim.x + threadIdx.x) >> 5;
    const int lane = threadIdx.x & 31;
    if (p >= n) return;
    const T tu = uv[2 * p], tv = uv[2 * p + 1];
    int x0, x1, y0, y1;
    if (!footprint((double)tu, r, gw, &x0, &x1) || !footprint((double)tv, r, gh, &y0, &y1))
        return;
    const T k2 = (T)inv2s2, te = (T)eps, ti = (T)inv1me, ta = (T)amax;
    const int nx = x1 - x0 + 1;
    const int total = nx * (y1 - y0 + 1);
    for (int k = lane; k < total; k += 32) {
        const int iy = k / nx;
        const int px = x0 + (k - iy * nx), py = y0 + iy;
        const T dx = (T)px + (T)0.5 - tu, dy = (T)py + (T)0.5 - tv;
        const T g = ex(-(dx * dx) * k2) * ex(-(dy * dy) * k2);
        T a = (g - te) * ti;
        if (!(a > (T)0)) continue;
        long long* cell = acc + (size_t)py * gw + px;
        double term;
        if (coverage) {
            if (a > ta) a = ta;
            if (*((volatile long long*)cell) < (long long)LOG_T_STOP) continue;
            term = log1p(-(double)a);
        } else {
            term = (double)a;
        }
        atomicAdd((unsigned long long*)cell, (unsigned long long)__double2ll_rn(term * FX_SCALE));
    }
}

template <typename T>
__device__ void pool_impl(const long long* __restrict__ acc, T* __restrict__ trans,
                          T* __restrict__ out, int w, int h, int s, int coverage, double norm) {
    const int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= w * h) return;
    const int px = i % w, py = i / w;
    const size_t gw = (size_t)w * s;
    T sum = (T)0;
    for (int sy = 0; sy < s; sy++) {
        for (int sx = 0; sx < s; sx++) {
            const size_t j = (size_t)(py * s + sy) * gw + (size_t)(px * s + sx);
            const double q = (double)acc[j] * FX_INV;
            if (coverage) {
                T t = (T)exp(q);
                if (t < (T)TRANS_FLOOR) t = (T)0;
                trans[j] = t;
                sum = sum + ((T)1 - t);
            } else {
                sum = sum + (T)q;
            }
        }
    }
    out[i] = sum * (T)norm;
}

template <typename T>
__device__ void backward_impl(const T* __restrict__ uv, int n, const T* __restrict__ trans,
                              const T* __restrict__ grad, T* __restrict__ guv, int w, int h,
                              int s, int coverage, double r, double inv2s2, double eps,
                              double inv1me, double amax, double norm, double dscale) {
    const long long p = ((long long)blockIdx.x * blockDim.x + threadIdx.x) >> 5;
    const int lane = threadIdx.x & 31;
    if (p >= n) return;
    const int gw = w * s, gh = h * s;
    const T tu = uv[2 * p], tv = uv[2 * p + 1];
    int x0, x1, y0, y1;
    if (!footprint((double)tu, r, gw, &x0, &x1) || !footprint((double)tv, r, gh, &y0, &y1))
        return;
    const T k2 = (T)inv2s2, te = (T)eps, ti = (T)inv1me, ta = (T)amax, tn = (T)norm;
    const int nx = x1 - x0 + 1;
    const int total = nx * (y1 - y0 + 1);
    T su = (T)0, sv = (T)0;
    for (int k = lane; k < total; k += 32) {
        const int iy = k / nx;
        const int px = x0 + (k - iy * nx), py = y0 + iy;
        const T dx = (T)px + (T)0.5 - tu, dy = (T)py + (T)0.5 - tv;
        const T g = ex(-(dx * dx) * k2) * ex(-(dy * dy) * k2);
        const T a = (g - te) * ti;
        const bool valid = coverage ? (a > (T)0 && a < ta) : (a > (T)0);
        if (!valid) continue;
        const T go = grad[(size_t)(py / s) * w + (px / s)] * tn;
        const T wgt = coverage ? go * trans[(size_t)py * gw + px] * g / ((T)1 - a) : go * g;
        su = su + wgt * dx;
        sv = sv + wgt * dy;
    }
    for (int off = 16; off > 0; off >>= 1) {
        su = su + __shfl_down_sync(0xffffffffu, su, off);
        sv = sv + __shfl_down_sync(0xffffffffu, sv, off);
    }
    if (lane == 0) {
        guv[2 * p] = su * (T)dscale;
        guv[2 * p + 1] = sv * (T)dscale;
    }
}

#define INSTANTIATE(T, SUF)                                                                   \
    extern "C" __global__ void splat_forward_##SUF(const T* uv, int n, long long* acc, int gw,  \
                                                   int gh, int coverage, double r,              \
                                                   double inv2s2, double eps, double inv1me,    \
                                                   double amax) {                               \
        forward_impl<T>(uv, n, acc, gw, gh, coverage, r, inv2s2, eps, inv1me, amax);            \
    }                                                                                           \
    extern "C" __global__ void splat_pool_##SUF(const long long* acc, T* trans, T* out, int w,  \
                                                int h, int s, int coverage, double norm) {      \
        pool_impl<T>(acc, trans, out, w, h, s, coverage, norm);                                 \
    }                                                                                           \
    extern "C" __global__ void splat_backward_##SUF(                                            \
        const T* uv, int n, const T* trans, const T* grad, T* guv, int w, int h, int s,         \
        int coverage, double r, double inv2s2, double eps, double inv1me, double amax,          \
        double norm, double dscale) {                                                           \
        backward_impl<T>(uv, n, trans, grad, guv, w, h, s, coverage, r, inv2s2, eps, inv1me,    \
                         amax, norm, dscale);                                                   \
    }

INSTANTIATE(float, f32)
INSTANTIATE(double, f64)
