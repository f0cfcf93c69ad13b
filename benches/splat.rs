//! Per-iteration breakdown of image inversion, like the chaotic-splatting paper's Table 2:
//! generation (chaos game), splat forward (framing + splat + pooling), loss (value and
//! gradient through candle, LPIPS excluded), splat backward (reverse pass to the maps), one
//! annealing candidate (forward + MS-MSE), and a whole gradient iteration of the image
//! problem (θ → loss and ∂loss/∂θ). With `--features cuda`, each setting again with the
//! splat on the GPU (`iteration_*_cuda`), where `full_iteration_fused` and
//! `anneal_candidate_fused` keep the image, the loss and its gradient on the GPU.
//!
//! Settings (2000 × 250 trajectories, 10 dropped: 480k points):
//! - `paper`: 1024² output, 5× supersampling, σ = 2.5 supersampled pixels, coverage;
//! - `cheap`: 256², 1×, σ = 1, additive.
//! - `demo`: 96², 4×, σ = 1, coverage, 1000 × 110 trajectories (what `ifslab demo` runs).
//!
//! LPIPS at 224² is timed in `benches/loss.rs`.

/// The allocator the `ifslab` binary ships with, so the figures are what users get.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Criterion group names: `iteration_paper`, `iteration_cheap`, `iteration_demo`.
const GROUP_SUFFIX: &str = "";

include!("common/splat_iteration.rs");

criterion_group!(benches, bench_splat);
criterion_main!(benches);
