//! `ifslab`: render, sample and invert Iterated Function Systems from the command line.
//! Arguments and progress bars only: what a run does is the `ifslab_experiments` library.

mod bars;
mod cmd;

use clap::{Parser, Subcommand};

// The splat iteration allocates and frees ~100 MiB of tape per call; glibc hands blocks that
// large back to the kernel (munmap, TLB shootdowns across threads, fresh page faults), which
// cost a third of an iteration. mimalloc keeps and reuses them (BENCHMARKS.md §2).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// ifslab — the fractal inverse problem, from images, point clouds and textures.
#[derive(Parser, Debug)]
#[command(name = "ifslab", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// The most memory a command may plan to use (8G, 512M, unlimited): a job whose
    /// buffers are estimated above it is refused before it allocates them, naming the flag
    /// to lower. [default: the IFSLAB_MAX_MEMORY environment variable, else 75 % of this
    /// machine's physical memory]
    #[arg(long, global = true, value_parser = ifslab::budget::parse_bytes, value_name = "SIZE")]
    max_memory: Option<u64>,
    /// The longest a command may plan to run (24h, 90m, unlimited): a job whose estimated
    /// time is above it (`render --points 1e15`) is refused before it starts, with the
    /// estimate. [default: the IFSLAB_MAX_WORK environment variable, else 24h]
    #[arg(long, global = true, value_parser = ifslab::budget::parse_duration, value_name = "DURATION")]
    max_work: Option<f64>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Recover a fractal from its render with no input files: the quick tour.
    Demo(cmd::demo::Args),
    /// Render a code file or a built-in code to a PNG with the evaluation renderer.
    Render(cmd::render::Args),
    /// Draw random codes with the Anderson–Farrell sampler.
    Sample(cmd::sample::Args),
    /// List the built-in codes.
    Codes,
    /// Fit an IFS of similitudes to a point cloud (any dimension) with EM.
    FitPoints(cmd::fit_points::Args),
    /// Fractal-coding texture upsampling: encode, upsample, reproduce the paper.
    Texture(cmd::texture::Args),
    /// Recover an IFS code from an image (differentiable splatting + a strategy).
    Invert(cmd::invert::Args),
    /// Recover an IFS code of space from pictures taken around it (views with cameras).
    Invert3d(cmd::invert3d::Args),
    /// Run what a config file describes: an image inversion, a points fit or a texture
    /// upsampling (its `problem` key).
    Run(cmd::run::Args),
    /// The chaotic-splatting paper's random test suite: make it, score a code against it.
    Suite(cmd::suite::Args),
    /// Run the runs of a sweep file: here, as one shard, or as a Slurm job array.
    Sweep(cmd::sweep::Args),
    /// Merge a sweep's results into one table, aggregates, plots and a Markdown report.
    Collect(cmd::collect::Args),
    /// Pack a sweep's finished runs into one compressed file (runs.jsonl.gz).
    Pack(cmd::pack::Args),
    /// Write packed runs back into run folders, and draw their pictures again.
    Unpack(cmd::unpack::Args),
    /// Draw a finished run folder's pictures again from its config, results and log.
    Redraw(cmd::redraw::Args),
    /// Plot the loss landscape of a run: the objective on a 2-D slice through its code.
    Landscape(cmd::landscape::Args),
    /// Where the LPIPS weights are looked for; `weights fetch` downloads and converts them.
    Weights(cmd::weights::Args),
    /// Segment-pattern IFSs with the differentiable SDF raster: fit control points to an
    /// image, render a pattern.
    Sdf(cmd::sdf::Args),
    /// A local web page that pans and zooms deep into a code's attractor, or a run's
    /// target and recovered code side by side.
    Serve(cmd::serve::Args),
    /// Fractal flames: render .flame files (flam3's algorithm), random flames, info, convert.
    Flame(cmd::flame::Args),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    // Ctrl-C, SIGTERM and SIGHUP: a checkpointed run stops at the end of its iteration with
    // a checkpoint (`--resume` continues it); anything else ends at once, as by default.
    ctrlc::set_handler(|| {
        ifslab::interrupt::on_signal();
    })?;
    if let Some(bytes) = cli.max_memory {
        ifslab::budget::set_process_budget(bytes);
    }
    if let Some(seconds) = cli.max_work {
        ifslab::budget::set_process_work_budget(seconds);
    }
    match cli.command {
        Command::Demo(a) => cmd::demo::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Sample(a) => cmd::sample::run(a),
        Command::Codes => cmd::codes::run(),
        Command::FitPoints(a) => cmd::fit_points::run(a),
        Command::Texture(a) => cmd::texture::run(a),
        Command::Invert(a) => cmd::invert::run(a),
        Command::Invert3d(a) => cmd::invert3d::run(a),
        Command::Run(a) => cmd::run::run(a),
        Command::Suite(a) => cmd::suite::run(a),
        Command::Sweep(a) => cmd::sweep::run(a),
        Command::Collect(a) => cmd::collect::run(a),
        Command::Pack(a) => cmd::pack::run(a),
        Command::Unpack(a) => cmd::unpack::run(a),
        Command::Redraw(a) => cmd::redraw::run(a),
        Command::Landscape(a) => cmd::landscape::run(a),
        Command::Weights(a) => cmd::weights::run(a),
        Command::Flame(a) => cmd::flame::run(a),
        Command::Sdf(a) => cmd::sdf::run(a),
        Command::Serve(a) => cmd::serve::run(a),
    }
}
