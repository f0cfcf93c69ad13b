// The image losses' GPU kernels (MS-MSE and D-SSIM, value and gradient), compiled at run time
// by NVRTC (see mod.rs).
//
// Every per-pixel value is computed with the CPU's operations in the CPU's order
// (src/loss/msmse.rs, src/loss/ssim.rs), and the module is compiled with --fmad=false, so the
// pyramid, the blurred moments, the SSIM map and both gradients are the CPU's bit for bit
// (IEEE division, no contraction into fused multiply-adds). Only the sums over pixels differ:
// they are f64, reduced in a fixed tree (each block sums a fixed share of the pixels, then one
// block per segment sums the blocks' partial sums in order), so they are deterministic but not
// in the CPU's order.

#define BLOCK 256
// Levels of the MS-MSE pyramid (msmse_levels ≤ 30: at most 31 levels).
#define MAX_LEVELS 32
// Longest SSIM window.
#define MAX_WINDOW 63

// Contiguous segments of a buffer, summed separately: [off[s], off[s + 1]).
struct Segments {
    long long off[MAX_LEVELS + 1];
    int count;
};

// The MS-MSE pyramid's layout in one buffer, and each level's gradient coefficient
// 2·w_l/N_l (as the CPU computes it, in f64).
struct Levels {
    long long off[MAX_LEVELS + 1];
    int w[MAX_LEVELS];
    int h[MAX_LEVELS];
    double c[MAX_LEVELS];
    int count;
};

// The normalised 1-D SSIM window (f64, as DSsim::kernel computes it).
struct Window {
    double k[MAX_WINDOW];
    int len;
};

__device__ __forceinline__ long long pixel() {
    return (long long)blockIdx.x * blockDim.x + threadIdx.x;
}

// d = pred − target (level 0 of the difference pyramid).
template <typename T>
__device__ void diff_impl(const T* __restrict__ p, const T* __restrict__ t, T* __restrict__ d,
                          long long n) {
    const long long i = pixel();
    if (i < n) d[i] = p[i] - t[i];
}

// One 2×2 average pooling, a block cut by an odd border averaging the pixels it has
// (msmse.rs `downsample2x`).
template <typename T>
__device__ void down_impl(const T* __restrict__ src, T* __restrict__ dst, int w, int h) {
    const int w2 = (w + 1) / 2, h2 = (h + 1) / 2;
    const long long i = pixel();
    if (i >= (long long)w2 * h2) return;
    const int x0 = 2 * (int)(i % w2), y0 = 2 * (int)(i / w2);
    const bool two_cols = x0 + 1 < w, two_rows = y0 + 1 < h;
    const T* r0 = src + (size_t)y0 * w;
    T s = r0[x0];
    double n = 1.0;
    if (two_cols) {
        s = s + r0[x0 + 1];
        n += 1.0;
    }
    if (two_rows) {
        const T* r1 = r0 + w;
        s = s + r1[x0];
        n += 1.0;
        if (two_cols) {
            s = s + r1[x0 + 1];
            n += 1.0;
        }
    }
    dst[i] = s / (T)n;
}

// Partial sums of f64(v) (or f64(v·v) when `square`) over each segment: block (b, s) sums the
// elements b, b + B, b + 2B, … of segment s in blocks of BLOCK threads (B = gridDim.x blocks),
// then reduces its threads in a fixed tree into partials[s·B + b].
template <typename T>
__device__ void partials_impl(const T* __restrict__ v, Segments seg, int square,
                              double* __restrict__ partials) {
    __shared__ double sh[BLOCK];
    const int s = blockIdx.y;
    const long long a = seg.off[s], b = seg.off[s + 1];
    const long long stride = (long long)gridDim.x * BLOCK;
    double acc = 0.0;
    for (long long i = a + (long long)blockIdx.x * BLOCK + threadIdx.x; i < b; i += stride) {
        const T x = v[i];
        acc += square ? (double)(x * x) : (double)x;
    }
    sh[threadIdx.x] = acc;
    __syncthreads();
    for (int k = BLOCK / 2; k > 0; k >>= 1) {
        if (threadIdx.x < k) sh[threadIdx.x] += sh[threadIdx.x + k];
        __syncthreads();
    }
    if (threadIdx.x == 0) partials[(size_t)s * gridDim.x + blockIdx.x] = sh[0];
}

// sums[s] = Σ_b partials[s·nb + b], one block per segment, in a fixed tree.
extern "C" __global__ void reduce_finish(const double* __restrict__ partials, int nb,
                                         double* __restrict__ sums) {
    __shared__ double sh[BLOCK];
    const int s = blockIdx.x;
    double acc = 0.0;
    for (int b = threadIdx.x; b < nb; b += BLOCK) acc += partials[(size_t)s * nb + b];
    sh[threadIdx.x] = acc;
    __syncthreads();
    for (int k = BLOCK / 2; k > 0; k >>= 1) {
        if (threadIdx.x < k) sh[threadIdx.x] += sh[threadIdx.x + k];
        __syncthreads();
    }
    if (threadIdx.x == 0) sums[s] = sh[0];
}

// ∂MS-MSE/∂pred at every pixel of level 0, times `weight`, written (or added, `accumulate`)
// into `grad`. The CPU pulls the gradient down level by level (g_l = Dᵀg_{l+1} + c_l·d_l);
// per pixel that is the chain of its ancestors, walked from the coarsest level down with the
// CPU's operations: g = c_L·d_L, then g = g / n_l + c_l·d_l, n_l the pixel count of the 2×2
// block of level l the pixel falls in.
template <typename T>
__device__ void msmse_grad_impl(const T* __restrict__ pyr, Levels lv, T weight, int accumulate,
                                T* __restrict__ grad) {
    const long long i = pixel();
    const int w0 = lv.w[0];
    if (i >= (long long)w0 * lv.h[0]) return;
    const int x = (int)(i % w0), y = (int)(i / w0);
    int l = lv.count - 1;
    T g = (T)lv.c[l] * pyr[lv.off[l] + (size_t)(y >> l) * lv.w[l] + (x >> l)];
    for (l = l - 1; l >= 0; l--) {
        const int xl = x >> l, yl = y >> l;
        const double nx = 2 * (xl >> 1) + 1 < lv.w[l] ? 2.0 : 1.0;
        const double ny = 2 * (yl >> 1) + 1 < lv.h[l] ? 2.0 : 1.0;
        g = g / (T)(nx * ny) + (T)lv.c[l] * pyr[lv.off[l] + (size_t)yl * lv.w[l] + xl];
    }
    const T out = weight * g;
    grad[i] = accumulate ? grad[i] + out : out;
}

// The horizontal pass of the zero-padded separable blur (ssim.rs `separable`) of SSIM's five
// inputs x, y, x², y², xy (`fill_moments`): tmp[c·n + i] = Σ_j k_j·in_c(x + j − r) over the
// taps inside the row, in tap order, from zero.
template <typename T>
__device__ void ssim_h5_impl(const T* __restrict__ x, const T* __restrict__ y,
                             T* __restrict__ tmp, int w, int h, Window win) {
    const long long n = (long long)w * h;
    const long long i = pixel();
    if (i >= n) return;
    const int px = (int)(i % w);
    const size_t row = (size_t)(i - px);
    const int r = win.len / 2;
    T a0 = (T)0, a1 = (T)0, a2 = (T)0, a3 = (T)0, a4 = (T)0;
    for (int j = 0; j < win.len; j++) {
        const int xx = px + j - r;
        if (xx < 0 || xx >= w) continue;
        const T kj = (T)win.k[j];
        const T a = x[row + xx], b = y[row + xx];
        a0 = a0 + kj * a;
        a1 = a1 + kj * b;
        a2 = a2 + kj * (a * a);
        a3 = a3 + kj * (b * b);
        a4 = a4 + kj * (a * b);
    }
    tmp[i] = a0;
    tmp[n + i] = a1;
    tmp[2 * n + i] = a2;
    tmp[3 * n + i] = a3;
    tmp[4 * n + i] = a4;
}

// The vertical pass of the five moments, then per pixel the SSIM value S (into `smap`) and the
// derivatives ∂S/∂μx, ∂S/∂mxx, ∂S/∂mxy (three planes of `deriv`), as DSsim::value_and_grad.
template <typename T>
__device__ void ssim_v5_impl(const T* __restrict__ tmp, T* __restrict__ smap,
                             T* __restrict__ deriv, int w, int h, Window win) {
    const long long n = (long long)w * h;
    const long long i = pixel();
    if (i >= n) return;
    const int px = (int)(i % w), py = (int)(i / w);
    const int r = win.len / 2;
    T b0 = (T)0, b1 = (T)0, b2 = (T)0, b3 = (T)0, b4 = (T)0;
    for (int j = 0; j < win.len; j++) {
        const int yy = py + j - r;
        if (yy < 0 || yy >= h) continue;
        const T kj = (T)win.k[j];
        const size_t q = (size_t)yy * w + px;
        b0 = b0 + kj * tmp[q];
        b1 = b1 + kj * tmp[n + q];
        b2 = b2 + kj * tmp[2 * n + q];
        b3 = b3 + kj * tmp[3 * n + q];
        b4 = b4 + kj * tmp[4 * n + q];
    }
    const T two = (T)2.0, one = (T)1.0;
    const T c1 = (T)(0.01 * 0.01), c2 = (T)(0.03 * 0.03);
    const T mx = b0, my = b1;
    const T fa1 = two * mx * my + c1;
    const T fa2 = two * (b4 - mx * my) + c2;
    const T fb1 = mx * mx + my * my + c1;
    const T fb2 = (b2 - mx * mx) + (b3 - my * my) + c2;
    const T inv = one / (fb1 * fb2);
    const T v = fa1 * fa2 * inv;
    smap[i] = v;
    deriv[i] = two * my * (fa2 - fa1) * inv - two * mx * v * (one / fb1 - one / fb2);
    deriv[n + i] = -v / fb2;
    deriv[2 * n + i] = two * fa1 * inv;
}

// The horizontal pass of the three derivative planes.
template <typename T>
__device__ void ssim_h3_impl(const T* __restrict__ deriv, T* __restrict__ tmp, int w, int h,
                             Window win) {
    const long long n = (long long)w * h;
    const long long i = pixel();
    if (i >= n) return;
    const int px = (int)(i % w);
    const size_t row = (size_t)(i - px);
    const int r = win.len / 2;
    T a0 = (T)0, a1 = (T)0, a2 = (T)0;
    for (int j = 0; j < win.len; j++) {
        const int xx = px + j - r;
        if (xx < 0 || xx >= w) continue;
        const T kj = (T)win.k[j];
        a0 = a0 + kj * deriv[row + xx];
        a1 = a1 + kj * deriv[n + row + xx];
        a2 = a2 + kj * deriv[2 * n + row + xx];
    }
    tmp[i] = a0;
    tmp[n + i] = a1;
    tmp[2 * n + i] = a2;
}

// The vertical pass of the three planes and the gradient
// ∂(1 − SSIM)/∂x = −(1/N)·[G∗(∂S/∂μx) + 2x·G∗(∂S/∂mxx) + y·G∗(∂S/∂mxy)], times `weight`,
// written (or added, `accumulate`) into `grad`.
template <typename T>
__device__ void ssim_v3_impl(const T* __restrict__ tmp, const T* __restrict__ x,
                             const T* __restrict__ y, int w, int h, Window win, double scale,
                             T weight, int accumulate, T* __restrict__ grad) {
    const long long n = (long long)w * h;
    const long long i = pixel();
    if (i >= n) return;
    const int px = (int)(i % w), py = (int)(i / w);
    const int r = win.len / 2;
    T b0 = (T)0, b1 = (T)0, b2 = (T)0;
    for (int j = 0; j < win.len; j++) {
        const int yy = py + j - r;
        if (yy < 0 || yy >= h) continue;
        const T kj = (T)win.k[j];
        const size_t q = (size_t)yy * w + px;
        b0 = b0 + kj * tmp[q];
        b1 = b1 + kj * tmp[n + q];
        b2 = b2 + kj * tmp[2 * n + q];
    }
    const T two = (T)2.0;
    const T g = (T)scale * (b0 + two * x[i] * b1 + y[i] * b2);
    const T out = weight * g;
    grad[i] = accumulate ? grad[i] + out : out;
}

#define INSTANTIATE(T, SUF)                                                                    \
    extern "C" __global__ void loss_diff_##SUF(const T* p, const T* t, T* d, long long n) {     \
        diff_impl<T>(p, t, d, n);                                                               \
    }                                                                                           \
    extern "C" __global__ void loss_down_##SUF(const T* src, T* dst, int w, int h) {            \
        down_impl<T>(src, dst, w, h);                                                           \
    }                                                                                           \
    extern "C" __global__ void loss_partials_##SUF(const T* v, Segments seg, int square,        \
                                                   double* partials) {                          \
        partials_impl<T>(v, seg, square, partials);                                             \
    }                                                                                           \
    extern "C" __global__ void msmse_grad_##SUF(const T* pyr, Levels lv, T weight,              \
                                                int accumulate, T* grad) {                      \
        msmse_grad_impl<T>(pyr, lv, weight, accumulate, grad);                                  \
    }                                                                                           \
    extern "C" __global__ void ssim_h5_##SUF(const T* x, const T* y, T* tmp, int w, int h,      \
                                             Window win) {                                      \
        ssim_h5_impl<T>(x, y, tmp, w, h, win);                                                  \
    }                                                                                           \
    extern "C" __global__ void ssim_v5_##SUF(const T* tmp, T* smap, T* deriv, int w, int h,     \
                                             Window win) {                                      \
        ssim_v5_impl<T>(tmp, smap, deriv, w, h, win);                                           \
    }                                                                                           \
    extern "C" __global__ void ssim_h3_##SUF(const T* deriv, T* tmp, int w, int h,              \
                                             Window win) {                                      \
        ssim_h3_impl<T>(deriv, tmp, w, h, win);                                                 \
    }                                                                                           \
    extern "C" __global__ void ssim_v3_##SUF(const T* tmp, const T* x, const T* y, int w,       \
                                             int h, Window win, double scale, T weight,         \
                                             int accumulate, T* grad) {                         \
        ssim_v3_impl<T>(tmp, x, y, w, h, win, scale, weight, accumulate, grad);                 \
    }

INSTANTIATE(float, f32)
INSTANTIATE(double, f64)
