//! `ifslab flame …`: fractal flames — render `.flame` files like flam3-render, make random
//! flames like flam3-genome, describe flames, turn affine codes into flames.

mod files;
mod learn;
mod render;

use files::{ConvertArgs, InfoArgs, RandomArgs, convert, info, random};
use learn::{LearnArgs, learn};
use render::{CompareArgs, RenderArgs, compare, render};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Render every flame of a .flame file (or the one named) to PNG, as flam3-render does.
    Render(RenderArgs),
    /// Random flames in flam3-genome's style, written as a .flame file.
    Random(RandomArgs),
    /// Describe the flames of a file: transforms, variations, estimated attractor box.
    Info(InfoArgs),
    /// An affine IFS code (JSON file or built-in name) as a linear flame.
    Convert(ConvertArgs),
    /// SSIM and PSNR of two renders' grey (luminance) images, e.g. ours against flam3's.
    Compare(CompareArgs),
    /// Learn a colour flame from an image (Bannister & Nowrouzezahrai): one or more layers
    /// of generators, composited; writes the learned .flame, renders and the loss curve.
    Learn(LearnArgs),
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::Render(a) => render(a),
        Command::Random(a) => random(a),
        Command::Info(a) => info(a),
        Command::Convert(a) => convert(a),
        Command::Compare(a) => compare(a),
        Command::Learn(a) => learn(a),
    }
}
