//! The per-iteration benchmark of `splat.rs` on the system allocator (glibc malloc), the
//! baseline for the allocator the `ifslab` binary ships with (mimalloc). Run both in one go:
//! `cargo bench --bench splat --bench splat_system_alloc`.
//!
//! The splat's forward pass allocates ~100 MiB of tape per call; glibc serves blocks that
//! large with mmap and returns them with munmap on free, so every iteration pays fresh page
//! faults and cross-thread TLB shootdowns. See BENCHMARKS.md §2.

/// Criterion group names: `iteration_{paper,cheap,demo}_system_alloc`.
const GROUP_SUFFIX: &str = "_system_alloc";

include!("common/splat_iteration.rs");

criterion_group!(benches, bench_splat);
criterion_main!(benches);
