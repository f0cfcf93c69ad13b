//! The splat kernel on an NVIDIA GPU (`device = "cuda"`, the `cuda` feature).
//!
//! The chaos game, the framing and the reverse scan through the trajectories stay on the CPU
//! (measured at the paper's setting on a 16-core host: 1.5 ms for the chaos game, about 7 ms
//! for all three); what the GPU does is the splat —
//! Gaussian footprints on the supersampled grid, blending, pooling — and its reverse pass to
//! per-point gradients, which are nearly all of an iteration's time on the CPU. Per call the
//! points go up (`8n` bytes in f32) and, on the reverse pass, `∂L/∂(u, v)` comes down, both
//! through page-locked host buffers kept between calls; the grid of `(s·W)·(s·H)` pixels stays
//! on the GPU (the transmittance the reverse pass needs is kept there in the tape).
//!
//! Two ways to use it:
//! - [`forward`] / [`backward`]: the image comes down and `∂L/∂image` goes up (what the candle
//!   op does, with the loss on the CPU);
//! - [`fused`]: forward, a loss evaluated on the image where it lies (the GPU loss of
//!   `crate::loss::cuda`), and the reverse pass from the gradient it leaves there — only the
//!   loss's scalars and the point gradients cross the bus
//!   (`render::splat::iteration` uses it).
//!
//! The kernels ([`SOURCE`], `splat.cu`) are compiled by NVRTC for the GPU found, once per
//! process; the driver and NVRTC are loaded at run time, so the crate builds without CUDA.
//! They are deterministic (integer atomics on fixed-point accumulators, fixed-order warp
//! reductions): the same points give bit-identical images and gradients on every run. They
//! agree with the CPU kernel to rounding (the CPU multiplies transmittances in point order,
//! the GPU sums their logarithms): see `tests/splat_cuda.rs`.

use std::any::{Any, TypeId};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

use cudarc::driver::{
    CudaContext, CudaFunction, CudaSlice, CudaStream, LaunchConfig, PinnedHostSlice, PushKernelArg,
};
use cudarc::nvrtc::{CompileOptions, compile_ptx_with_opts};

use super::kernel::{Blend, SplatGrid, SplatReal};
use crate::error::{Error, Result};

/// The kernels' CUDA C++ source.
pub const SOURCE: &str = include_str!("splat.cu");

/// Threads per block: eight warps, one point per warp.
const BLOCK: u32 = 256;

/// Precisions the kernels exist in ([`crate::math::GpuScalar`]).
pub use crate::math::GpuScalar;

struct Gpu {
    stream: Arc<CudaStream>,
    name: String,
    capability: (i32, i32),
    functions: HashMap<String, CudaFunction>,
    /// What calls reuse; the lock also keeps one call's work together on the stream, and
    /// every call synchronises the stream before it lets go (so the page-locked buffers are
    /// free when the next call takes them).
    work: Mutex<Workspace>,
}

/// Buffers reused across calls.
#[derive(Default)]
struct Workspace {
    /// The fixed-point accumulators of the supersampled grid.
    acc: Option<CudaSlice<i64>>,
    /// Page-locked host buffers, per precision and direction (`true`: the points going up;
    /// `false`: their gradients coming down), each a `PinnedHostSlice<T>` grown as needed.
    pinned: HashMap<(TypeId, bool), Box<dyn Any + Send>>,
}

impl Workspace {
    /// The first `len` values of this precision's page-locked buffer for direction `up`.
    fn pinned<T: GpuScalar>(
        &mut self,
        ctx: &Arc<CudaContext>,
        up: bool,
        len: usize,
    ) -> Result<&mut [T]> {
        let key = (TypeId::of::<T>(), up);
        let fits = self
            .pinned
            .get(&key)
            .and_then(|b| b.downcast_ref::<PinnedHostSlice<T>>())
            .is_some_and(|p| p.len() >= len);
        if !fits {
            // The old buffer is freed (on this thread, whose context is current) before the
            // larger one is taken.
            self.pinned.remove(&key);
            // Plain page-locked memory (not write-combined: the gradients are read on the
            // host).
            // SAFETY: the memory is uninitialised; it is zeroed below before any use.
            let mut p = unsafe { ctx.alloc_pinned_with_flags::<T>(len.max(1), 0) }
                .map_err(driver("allocating page-locked host memory"))?;
            let ptr = p
                .as_mut_ptr()
                .map_err(driver("mapping page-locked host memory"))?;
            // SAFETY: `ptr` holds `p.len()` values of a type valid as all-zero bits.
            unsafe { std::ptr::write_bytes(ptr, 0, p.len()) };
            self.pinned.insert(key, Box::new(p));
        }
        let p = self
            .pinned
            .get_mut(&key)
            .and_then(|b| b.downcast_mut::<PinnedHostSlice<T>>())
            .expect("a buffer of this type was stored above");
        let all = p
            .as_mut_slice()
            .map_err(driver("mapping page-locked host memory"))?;
        Ok(&mut all[..len])
    }
}

static GPU: OnceLock<std::result::Result<Gpu, String>> = OnceLock::new();

fn device_error(message: impl Into<String>) -> Error {
    Error::Device(message.into())
}

fn gpu() -> Result<&'static Gpu> {
    GPU.get_or_init(init)
        .as_ref()
        .map_err(|e| device_error(e.clone()))
}

/// The stream every GPU call of the crate runs on and the GPU's compute capability (the
/// loss kernels are compiled for it and run on the same stream).
pub(crate) fn device() -> Result<(&'static Arc<CudaStream>, (i32, i32))> {
    let g = gpu()?;
    Ok((&g.stream, g.capability))
}

impl Gpu {
    fn lock(&self) -> Result<MutexGuard<'_, Workspace>> {
        self.work
            .lock()
            .map_err(|_| device_error("GPU state lock poisoned"))
    }
}

/// `Ok` when the GPU backend is ready (driver, GPU, kernels compiled), else why not. Cheap
/// after the first call: every `SplatConfig::validate` asks.
pub fn available() -> Result<()> {
    gpu().map(|_| ())
}

/// The GPU the splat runs on (`"NVIDIA H100 80GB HBM3 (compute 9.0)"`), or why there is none.
pub fn describe() -> Result<String> {
    let g = gpu()?;
    Ok(format!(
        "{} (compute {}.{})",
        g.name, g.capability.0, g.capability.1
    ))
}

fn init() -> std::result::Result<Gpu, String> {
    // SAFETY: each probe opens the library with `dlopen` and closes it again.
    if !unsafe { cudarc::driver::sys::is_culib_present() } {
        return Err(
            "device = \"cuda\" needs an NVIDIA GPU and its driver, but no CUDA driver \
                    (libcuda.so) was found; use device = \"cpu\""
                .into(),
        );
    }
    // SAFETY: as above.
    if !unsafe { cudarc::nvrtc::sys::is_culib_present() } {
        return Err(
            "device = \"cuda\" compiles its kernels with NVRTC, but libnvrtc.so.13 was \
                    not found: install the CUDA 13 toolkit (or the `nvidia-cuda-nvrtc` wheel) \
                    and put its library folder on LD_LIBRARY_PATH"
                .into(),
        );
    }
    let count = CudaContext::device_count()
        .map_err(|e| format!("the CUDA driver could not be initialised: {e}"))?;
    if count < 1 {
        return Err("the CUDA driver is installed but reports no GPU; use device = \"cpu\"".into());
    }
    let ctx = CudaContext::new(0).map_err(|e| format!("cannot open GPU 0: {e}"))?;
    let capability = ctx
        .compute_capability()
        .map_err(|e| format!("cannot read GPU 0's compute capability: {e}"))?;
    let name = ctx.name().unwrap_or_else(|_| "GPU 0".into());
    let opts = CompileOptions {
        options: vec![format!(
            "--gpu-architecture=compute_{}{}",
            capability.0, capability.1
        )],
        name: Some("ifslab_splat.cu".into()),
        ..Default::default()
    };
    let ptx = compile_ptx_with_opts(SOURCE, opts)
        .map_err(|e| format!("NVRTC could not compile the splat kernels: {e:?}"))?;
    let module = ctx
        .load_module(ptx)
        .map_err(|e| format!("the driver could not load the splat kernels: {e}"))?;
    let mut functions = HashMap::new();
    for kernel in ["splat_forward", "splat_pool", "splat_backward"] {
        for suffix in [f32::SUFFIX, f64::SUFFIX] {
            let name = format!("{kernel}_{suffix}");
            let f = module
                .load_function(&name)
                .map_err(|e| format!("kernel {name} is missing: {e}"))?;
            functions.insert(name, f);
        }
    }
    Ok(Gpu {
        stream: ctx.default_stream(),
        name,
        capability,
        functions,
        work: Mutex::new(Workspace::default()),
    })
}

/// Compiles the kernels with NVRTC for `arch` (e.g. `"compute_90"`) without a GPU: the check
/// that the source is valid CUDA C++ on a machine with only NVRTC. Returns the PTX's length.
pub fn compile_only(arch: &str) -> Result<usize> {
    // SAFETY: as in `init`.
    if !unsafe { cudarc::nvrtc::sys::is_culib_present() } {
        return Err(device_error("libnvrtc.so.13 was not found"));
    }
    let opts = CompileOptions {
        options: vec![format!("--gpu-architecture={arch}")],
        ..Default::default()
    };
    compile_ptx_with_opts(SOURCE, opts)
        .map(|p| p.to_src().len())
        .map_err(|e| device_error(format!("NVRTC: {e:?}")))
}

/// Makes the GPU's context current on this thread (each call may come from another thread:
/// the test harness, rayon, a sweep's workers).
pub(crate) fn bind(st: &CudaStream) -> Result<()> {
    st.context()
        .bind_to_thread()
        .map_err(driver("making the GPU context current"))
}

/// Turns a driver error into the crate's, saying what was being done.
pub(crate) fn driver(what: &str) -> impl Fn(cudarc::driver::DriverError) -> Error + '_ {
    move |e| device_error(format!("{what}: {e}"))
}

/// The footprint's constants as the kernels take them.
struct Launch {
    coverage: i32,
    r: f64,
    inv2s2: f64,
    eps: f64,
    inv1me: f64,
    amax: f64,
    norm: f64,
    dscale: f64,
}

impl Launch {
    /// The CPU kernel's constants (`SplatGrid::footprint_constants`), as kernel arguments.
    fn new(grid: &SplatGrid) -> Self {
        let (k, r) = grid.footprint_constants();
        Launch {
            coverage: i32::from(grid.blend == Blend::Coverage),
            r,
            inv2s2: k.inv2s2,
            eps: k.eps,
            inv1me: k.inv1me,
            amax: k.amax,
            norm: k.norm,
            dscale: k.dscale,
        }
    }
}

fn dims(grid: &SplatGrid) -> Result<(i32, i32, i32, usize)> {
    let s = grid.supersample;
    let sub = (grid.width * s).checked_mul(grid.height * s);
    match sub {
        Some(n) if n < i32::MAX as usize => {
            Ok((grid.width as i32, grid.height as i32, s as i32, n))
        }
        _ => Err(Error::param(
            "size",
            "the supersampled grid is too large for the GPU splat (over 2^31 pixels)",
        )),
    }
}

fn per_point_launch(n: usize) -> LaunchConfig {
    LaunchConfig {
        grid_dim: ((n as u64 * 32).div_ceil(BLOCK as u64) as u32, 1, 1),
        block_dim: (BLOCK, 1, 1),
        shared_mem_bytes: 0,
    }
}

/// Events recorded between the stages of a call, when profiling.
pub(crate) type Marks = Option<Vec<(&'static str, cudarc::driver::CudaEvent)>>;

/// Records an event labelled `label` (the end of a stage) when profiling.
pub(crate) fn mark(st: &CudaStream, marks: &mut Marks, label: &'static str) -> Result<()> {
    if let Some(m) = marks {
        let e = st
            .record_event(Some(cudarc::driver::sys::CUevent_flags::CU_EVENT_DEFAULT))
            .map_err(driver("recording an event"))?;
        m.push((label, e));
    }
    Ok(())
}

/// The GPU time of each stage between the recorded events: `(stage, ms)`, in order.
pub(crate) fn stage_times(marks: Marks) -> Result<Vec<(&'static str, f64)>> {
    let m = marks.unwrap_or_default();
    let mut out = Vec::new();
    for w in m.windows(2) {
        let ms = w[0]
            .1
            .elapsed_ms(&w[1].1)
            .map_err(driver("reading an event"))?;
        out.push((w[1].0, ms as f64));
    }
    Ok(out)
}

/// GPU time of each stage of one forward and one backward call on `uv` (milliseconds, in
/// order: `(stage, ms)`, each stage ending at its label), measured with CUDA events.
pub fn profile<T: SplatReal>(
    grid: &SplatGrid,
    uv: &[[T; 2]],
    grad_image: &[T],
) -> Result<Vec<(&'static str, f64)>> {
    let mut marks: Marks = Some(Vec::new());
    let (_, state) = forward_marked(grid, uv.len(), |d| d.copy_from_slice(uv), &mut marks)?;
    backward_marked(grid, &state, grad_image, &mut marks)?;
    stage_times(marks)
}

/// Buffers on the GPU that may be dropped on any thread: the driver frees memory in the
/// context current on the calling thread, so the context is made current first (a free on a
/// thread without it fails, and the driver wrapper reports that failure at the next call).
struct DeviceBuffers<T: GpuScalar> {
    uv: CudaSlice<T>,
    trans: Option<CudaSlice<T>>,
    stream: Arc<CudaStream>,
}

impl<T: GpuScalar> Drop for DeviceBuffers<T> {
    fn drop(&mut self) {
        // Nothing to report to: a failed bind surfaces at the next GPU call.
        let _ = self.stream.context().bind_to_thread();
    }
}

/// A buffer on the GPU that may be kept anywhere and dropped on any thread (see
/// `DeviceBuffers`): a loss's target image, kept between calls.
pub struct DeviceSlice<T: GpuScalar> {
    slice: CudaSlice<T>,
    stream: Arc<CudaStream>,
}

impl<T: GpuScalar> DeviceSlice<T> {
    /// Copies `data` to the GPU.
    pub fn upload(data: &[T]) -> Result<Self> {
        let g = gpu()?;
        bind(&g.stream)?;
        let slice = g
            .stream
            .clone_htod(data)
            .map_err(driver("uploading to the GPU"))?;
        g.stream
            .synchronize()
            .map_err(driver("uploading to the GPU"))?;
        Ok(DeviceSlice {
            slice,
            stream: Arc::clone(&g.stream),
        })
    }

    /// The buffer.
    pub(crate) fn slice(&self) -> &CudaSlice<T> {
        &self.slice
    }

    /// The number of values.
    pub fn len(&self) -> usize {
        self.slice.len()
    }

    /// Whether it holds no value.
    pub fn is_empty(&self) -> bool {
        self.slice.len() == 0
    }
}

impl<T: GpuScalar> Drop for DeviceSlice<T> {
    fn drop(&mut self) {
        // As for `DeviceBuffers`.
        let _ = self.stream.context().bind_to_thread();
    }
}

impl<T: GpuScalar> std::fmt::Debug for DeviceSlice<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DeviceSlice {{ len: {} }}", self.slice.len())
    }
}

/// What the GPU forward pass keeps for its reverse pass: the points and (coverage) the
/// transmittance of every supersampled pixel, on the GPU.
pub struct CudaSplatState<T: GpuScalar> {
    inner: Arc<DeviceBuffers<T>>,
    n: usize,
}

impl<T: GpuScalar> Clone for CudaSplatState<T> {
    fn clone(&self) -> Self {
        CudaSplatState {
            inner: Arc::clone(&self.inner),
            n: self.n,
        }
    }
}

impl<T: GpuScalar> std::fmt::Debug for CudaSplatState<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "CudaSplatState {{ points: {} }}", self.n)
    }
}

/// Forward on the GPU: the pooled image (row-major `height × width`) and the state for the
/// reverse pass.
pub fn forward<T: SplatReal>(
    grid: &SplatGrid,
    uv: &[[T; 2]],
) -> Result<(Vec<T>, CudaSplatState<T>)> {
    forward_with(grid, uv.len(), |d| d.copy_from_slice(uv))
}

/// [`forward`] for `n` points that `fill` writes straight into the page-locked buffer they
/// are uploaded from (the framing projects into it, sparing a copy).
pub fn forward_with<T: SplatReal>(
    grid: &SplatGrid,
    n: usize,
    fill: impl FnOnce(&mut [[T; 2]]),
) -> Result<(Vec<T>, CudaSplatState<T>)> {
    forward_marked(grid, n, fill, &mut None)
}

fn forward_marked<T: SplatReal>(
    grid: &SplatGrid,
    n: usize,
    fill: impl FnOnce(&mut [[T; 2]]),
    marks: &mut Marks,
) -> Result<(Vec<T>, CudaSplatState<T>)> {
    let g = gpu()?;
    let st = &g.stream;
    bind(st)?;
    let mut work = g.lock()?;
    let out = (|| {
        let (out, state) = splat_on_gpu(g, &mut work, grid, n, fill, marks)?;
        let image = st
            .clone_dtoh(&out)
            .map_err(driver("downloading the image"))?;
        mark(st, marks, "download the image")?;
        Ok((image, state))
    })();
    synchronised(st, out)
}

/// `out`, once the stream has finished everything queued (also after an error: the
/// page-locked buffers must be idle before the workspace is let go).
fn synchronised<R>(st: &CudaStream, out: Result<R>) -> Result<R> {
    let synced = st.synchronize().map_err(driver("synchronising the GPU"));
    let out = out?;
    synced?;
    Ok(out)
}

/// The forward pass, its image left on the GPU. The caller holds the workspace and
/// synchronises the stream before letting it go (the points' upload from the page-locked
/// buffer may still be in flight).
fn splat_on_gpu<T: SplatReal>(
    g: &Gpu,
    work: &mut Workspace,
    grid: &SplatGrid,
    n: usize,
    fill: impl FnOnce(&mut [[T; 2]]),
    marks: &mut Marks,
) -> Result<(CudaSlice<T>, CudaSplatState<T>)> {
    if n >= i32::MAX as usize {
        return Err(Error::param(
            "trajectories",
            "too many points for the GPU splat",
        ));
    }
    let (w, h, s, sub) = dims(grid)?;
    let k = Launch::new(grid);
    let st = &g.stream;
    mark(st, marks, "start")?;
    let host = work.pinned::<T>(st.context(), true, 2 * n)?;
    fill(host.as_chunks_mut::<2>().0);
    // SAFETY: every value is written by the copy below before a kernel reads it.
    let mut d_uv = unsafe { st.alloc::<T>(2 * n) }.map_err(driver("allocating the points"))?;
    st.memcpy_htod(&*host, &mut d_uv)
        .map_err(driver("uploading the points"))?;
    mark(st, marks, "upload the points (page-locked)")?;
    if work.acc.as_ref().is_none_or(|a| a.len() < sub) {
        work.acc = None;
        work.acc = Some(
            st.alloc_zeros::<i64>(sub)
                .map_err(driver("allocating the splat grid"))?,
        );
    }
    let acc = work.acc.as_mut().expect("allocated above");
    let mut acc_view = acc.slice_mut(0..sub);
    st.memset_zeros(&mut acc_view)
        .map_err(driver("clearing the splat grid"))?;
    mark(st, marks, "clear the grid")?;
    let f = &g.functions[&format!("splat_forward_{}", T::SUFFIX)];
    let (gw, gh) = (w * s, h * s);
    let n32 = n as i32;
    if n > 0 {
        let mut b = st.launch_builder(f);
        b.arg(&d_uv)
            .arg(&n32)
            .arg(&mut acc_view)
            .arg(&gw)
            .arg(&gh)
            .arg(&k.coverage)
            .arg(&k.r)
            .arg(&k.inv2s2)
            .arg(&k.eps)
            .arg(&k.inv1me)
            .arg(&k.amax);
        // SAFETY: the arguments match `splat_forward_*`'s signature; `d_uv` holds 2n values
        // and the grid `gw·gh` accumulators.
        unsafe { b.launch(per_point_launch(n)) }.map_err(driver("launching splat_forward"))?;
    }
    mark(st, marks, "splat (forward kernel)")?;
    let mut trans = st
        .alloc_zeros::<T>(if k.coverage == 1 { sub } else { 1 })
        .map_err(driver("allocating the transmittance"))?;
    let mut out = st
        .alloc_zeros::<T>((w * h) as usize)
        .map_err(driver("allocating the image"))?;
    let f = &g.functions[&format!("splat_pool_{}", T::SUFFIX)];
    let mut b = st.launch_builder(f);
    b.arg(&mut acc_view)
        .arg(&mut trans)
        .arg(&mut out)
        .arg(&w)
        .arg(&h)
        .arg(&s)
        .arg(&k.coverage)
        .arg(&k.norm);
    let cfg = LaunchConfig {
        grid_dim: (((w * h) as u32).div_ceil(BLOCK), 1, 1),
        block_dim: (BLOCK, 1, 1),
        shared_mem_bytes: 0,
    };
    // SAFETY: the arguments match `splat_pool_*`; `trans` holds `sub` values when coverage.
    unsafe { b.launch(cfg) }.map_err(driver("launching splat_pool"))?;
    mark(st, marks, "allocate + transmittance + pool")?;
    let trans = (k.coverage == 1).then_some(trans);
    Ok((
        out,
        CudaSplatState {
            inner: Arc::new(DeviceBuffers {
                uv: d_uv,
                trans,
                stream: Arc::clone(st),
            }),
            n,
        },
    ))
}

/// Reverse on the GPU: `∂L/∂(u, v)` of every point from `∂L/∂image`.
pub fn backward<T: SplatReal>(
    grid: &SplatGrid,
    state: &CudaSplatState<T>,
    grad_image: &[T],
) -> Result<Vec<[f64; 2]>> {
    backward_marked(grid, state, grad_image, &mut None)
}

fn backward_marked<T: SplatReal>(
    grid: &SplatGrid,
    state: &CudaSplatState<T>,
    grad_image: &[T],
    marks: &mut Marks,
) -> Result<Vec<[f64; 2]>> {
    let g = gpu()?;
    if state.n == 0 {
        return Ok(Vec::new());
    }
    let st = &g.stream;
    bind(st)?;
    let mut work = g.lock()?;
    let d_grad = st
        .clone_htod(grad_image)
        .map_err(driver("uploading the image gradient"))?;
    mark(st, marks, "upload the image gradient")?;
    backward_on_gpu(g, &mut work, grid, state, &d_grad, marks)
}

/// The reverse pass from an image gradient on the GPU; the point gradients come down
/// through the page-locked buffer, and the stream is synchronised on return.
fn backward_on_gpu<T: SplatReal>(
    g: &Gpu,
    work: &mut Workspace,
    grid: &SplatGrid,
    state: &CudaSplatState<T>,
    d_grad: &CudaSlice<T>,
    marks: &mut Marks,
) -> Result<Vec<[f64; 2]>> {
    let (w, h, s, _) = dims(grid)?;
    let k = Launch::new(grid);
    let n = state.n;
    if n == 0 {
        return Ok(Vec::new());
    }
    if d_grad.len() != (w * h) as usize {
        return Err(Error::Shape(format!(
            "image gradient has {} values for a {w}×{h} image",
            d_grad.len()
        )));
    }
    let (d_uv, trans) = (&state.inner.uv, &state.inner.trans);
    if (trans.is_some()) != (k.coverage == 1) {
        return Err(Error::Shape(
            "the GPU tape was recorded with another blend mode".into(),
        ));
    }
    let st = &g.stream;
    let dummy;
    let trans = match trans {
        Some(t) => t,
        None => {
            dummy = st.alloc_zeros::<T>(1).map_err(driver("allocating"))?;
            &dummy
        }
    };
    // SAFETY: the kernel writes every one of the 2n values (lane 0 of each point's warp).
    let mut guv =
        unsafe { st.alloc::<T>(2 * n) }.map_err(driver("allocating the point gradients"))?;
    let f = &g.functions[&format!("splat_backward_{}", T::SUFFIX)];
    let n32 = n as i32;
    let mut b = st.launch_builder(f);
    b.arg(d_uv)
        .arg(&n32)
        .arg(trans)
        .arg(d_grad)
        .arg(&mut guv)
        .arg(&w)
        .arg(&h)
        .arg(&s)
        .arg(&k.coverage)
        .arg(&k.r)
        .arg(&k.inv2s2)
        .arg(&k.eps)
        .arg(&k.inv1me)
        .arg(&k.amax)
        .arg(&k.norm)
        .arg(&k.dscale);
    // SAFETY: the arguments match `splat_backward_*`; `d_grad` is `w·h` values (checked
    // above), `guv` 2n.
    unsafe { b.launch(per_point_launch(n)) }.map_err(driver("launching splat_backward"))?;
    mark(st, marks, "backward kernel")?;
    let host = work.pinned::<T>(st.context(), false, 2 * n)?;
    st.memcpy_dtoh(&guv, host)
        .map_err(driver("downloading the point gradients"))?;
    st.synchronize()
        .map_err(driver("downloading the point gradients"))?;
    mark(st, marks, "download the point gradients (page-locked)")?;
    Ok(host
        .chunks_exact(2)
        .map(|p| [p[0].to_f64().unwrap_or(0.0), p[1].to_f64().unwrap_or(0.0)])
        .collect())
}

/// What a loss evaluated on the GPU by [`fused`] returns: its result for the caller, and
/// `∂L/∂image` on the GPU when the reverse pass should run.
pub type GpuLossResult<T, R> = Result<(R, Option<CudaSlice<T>>)>;

/// One iteration with the image kept on the GPU: the forward pass of the `n` points `fill`
/// writes, `loss` on the image where it lies (on the same stream), and, when `loss` leaves
/// `∂L/∂image` there, the reverse pass from it. Only what `loss` returns and the points'
/// gradients come back to the host.
pub fn fused<T: SplatReal, R>(
    grid: &SplatGrid,
    n: usize,
    fill: impl FnOnce(&mut [[T; 2]]),
    loss: impl FnOnce(&Arc<CudaStream>, &CudaSlice<T>) -> GpuLossResult<T, R>,
) -> Result<(R, Option<Vec<[f64; 2]>>)> {
    fused_marked(grid, n, fill, |st, image, _| loss(st, image), &mut None)
}

/// [`fused`], recording an event after each stage when `marks` is `Some` (handed to `loss`
/// to mark its own stages).
pub(crate) fn fused_marked<T: SplatReal, R>(
    grid: &SplatGrid,
    n: usize,
    fill: impl FnOnce(&mut [[T; 2]]),
    loss: impl FnOnce(&Arc<CudaStream>, &CudaSlice<T>, &mut Marks) -> GpuLossResult<T, R>,
    marks: &mut Marks,
) -> Result<(R, Option<Vec<[f64; 2]>>)> {
    let g = gpu()?;
    let st = &g.stream;
    bind(st)?;
    let mut work = g.lock()?;
    let out = (|| {
        let (image, state) = splat_on_gpu(g, &mut work, grid, n, fill, marks)?;
        let (r, grad) = loss(st, &image, marks)?;
        let guv = match grad {
            Some(d) => Some(backward_on_gpu(g, &mut work, grid, &state, &d, marks)?),
            None => None,
        };
        Ok((r, guv))
    })();
    synchronised(st, out)
}
