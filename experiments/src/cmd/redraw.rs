//! `ifslab redraw RUN_DIR…`: a finished run folder's pictures drawn again from its config,
//! results and log (committed runs keep no pictures: see `ifslab pack`).

use std::path::PathBuf;

use ifslab_experiments::runs::redraw_pictures;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Finished run folders (an image inversion gets its renders, target, truth, zoom strip
    /// and loss plot; a learned flame its loss plot).
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    for d in &a.dirs {
        let files = redraw_pictures(d)?;
        println!("{}: {} pictures", d.display(), files.len());
    }
    Ok(())
}
